"""Camera motion relative to the road: the scenario's ``camera_motion:`` block and its pose model.

The *true* camera of frame ``k`` is the nominal calibration (``camera:``) turned by

    pitch_k = mount.pitch_deg + suspension_k + vibration_pitch_k      (deg, + = down)
    roll_k  = mount.roll_deg  + vibration_roll_k                        (deg, + = right side down)

about the camera's optical centre (its height and position are unchanged; the rotation
about the vehicle's pitch centre moves the camera by millimetres, ignored).

* **mount**: constant mounting error (true minus nominal).
* **suspension**: body pitch responding to the ego's longitudinal acceleration ``a``
  (m/s^2, from its speed between frames, clipped to +-``ACCEL_LIMIT_MPS2``): the static
  pitch ``-pitch_deg_per_mps2 * a`` (braking, a < 0, pitches the nose and the camera down)
  filtered by a spring-damper of natural frequency ``natural_hz`` and damping ratio
  ``damping_ratio`` (integrated in 8 sub-steps per frame), at rest at frame 0.
* **vibration**: road roughness as a seeded random process: the sum of ``components``
  sinusoids of equal amplitude ``amplitude / components``, frequencies drawn uniformly in
  ``band_hz`` and phases uniformly in [0, 2 pi) from ``seed`` (default: the scenario's seed),
  so ``|vibration| <= amplitude`` (the peak; RMS = amplitude / sqrt(2 components)).

Time is ``k / fps`` (frames are indexed by step count). The same scenario and seed give the
same pose sequence, and the pose of frame ``k`` does not depend on how many frames are rendered.
The pipeline never sees any of this: it gets only the nominal calibration.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from monorarp.core.camera import CameraError, CameraModel

ACCEL_LIMIT_MPS2 = 12.0      # the largest deceleration a scenario event may ask for
SUSPENSION_SUBSTEPS = 8
_OVERSHOOT = 2.0             # an under-damped second-order step response stays below twice its static value


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Mount(_Model):
    """Constant mounting error of the camera: true minus nominal (deg)."""

    pitch_deg: float = Field(0.0, ge=-10, le=10, description="+ = tilted further down than calibrated")
    roll_deg: float = Field(0.0, ge=-10, le=10, description="+ = right side down")


class Suspension(_Model):
    """Body pitch from the ego's longitudinal acceleration (spring-damper)."""

    pitch_deg_per_mps2: float = Field(0.0, ge=0, le=1.0, description=(
        "static pitch per m/s^2 of deceleration, deg/(m/s^2) (cars: about 0.1)"))
    natural_hz: float = Field(1.5, gt=0, le=10)
    damping_ratio: float = Field(0.5, gt=0, le=3)


class Vibration(_Model):
    """Road-roughness vibration: a seeded sum of sinusoids in a frequency band."""

    pitch_amplitude_deg: float = Field(0.0, ge=0, le=10, description="peak |pitch vibration|, deg")
    roll_amplitude_deg: float = Field(0.0, ge=0, le=10, description="peak |roll vibration|, deg")
    band_hz: tuple[float, float] = (1.0, 3.0)
    components: int = Field(2, ge=1, le=16)

    @model_validator(mode="after")
    def _band(self) -> "Vibration":
        lo, hi = self.band_hz
        if not 0 < lo <= hi:
            raise ValueError(f"band_hz must be [low, high] with 0 < low <= high, got [{lo}, {hi}]")
        return self


class CameraMotion(_Model):
    """The scenario's ``camera_motion:`` block (absent = a camera that never moves on its mount)."""

    seed: int | None = Field(None, description="vibration seed; default: the scenario's seed")
    mount: Mount = Mount()
    suspension: Suspension = Suspension()
    vibration: Vibration = Vibration()

    def pitch_bound_deg(self) -> float:
        """Largest |pitch - nominal| the model can produce (deg)."""
        return (abs(self.mount.pitch_deg) + self.vibration.pitch_amplitude_deg
                + _OVERSHOOT * self.suspension.pitch_deg_per_mps2 * ACCEL_LIMIT_MPS2)

    def roll_bound_deg(self) -> float:
        return abs(self.mount.roll_deg) + self.vibration.roll_amplitude_deg

    def check(self, nominal: CameraModel, fps: float) -> None:
        """ValueError naming the field when the motion is impossible for this camera and frame rate."""
        if self.vibration.band_hz[1] > fps / 2:
            raise ValueError(f"camera_motion.vibration.band_hz: {self.vibration.band_hz[1]} Hz is above the "
                             f"frames' Nyquist frequency ({fps / 2:g} Hz at {fps:g} fps)")
        if self.suspension.natural_hz > fps / 2:
            raise ValueError(f"camera_motion.suspension.natural_hz: {self.suspension.natural_hz} Hz is above "
                             f"the frames' Nyquist frequency ({fps / 2:g} Hz at {fps:g} fps)")
        pb, rb = math.radians(self.pitch_bound_deg()), math.radians(self.roll_bound_deg())
        if self.vibration.pitch_amplitude_deg > 0:
            field = "camera_motion.vibration.pitch_amplitude_deg"
        elif self.suspension.pitch_deg_per_mps2 > 0:
            field = "camera_motion.suspension.pitch_deg_per_mps2"
        else:
            field = "camera_motion.mount.pitch_deg"
        for p in (nominal.pitch_rad - pb, nominal.pitch_rad + pb):   # roll only lowers |horizon shift|
            try:
                replace(nominal, pitch_rad=p)
            except CameraError as e:
                raise ValueError(f"{field}: the pitch can reach {math.degrees(p):.2f} deg: {e}") from None
        try:
            replace(nominal, roll_rad=nominal.roll_rad + rb)
        except CameraError as e:
            raise ValueError(f"camera_motion.vibration.roll_amplitude_deg: {e}") from None


class CameraMotionModel:
    """Per-frame true camera of one scenario run; call :meth:`camera` with frames in order."""

    def __init__(self, motion: CameraMotion, nominal: CameraModel, fps: float, scenario_seed: int) -> None:
        self.motion, self.nominal, self.fps = motion, nominal, float(fps)
        seed = scenario_seed if motion.seed is None else motion.seed
        rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, 0x5EED_CA3])
        vib = motion.vibration
        n = vib.components
        self._f = rng.uniform(vib.band_hz[0], vib.band_hz[1], size=(2, n))   # pitch, roll (Hz)
        self._phi = rng.uniform(0.0, 2 * math.pi, size=(2, n))
        self._amp = np.array([vib.pitch_amplitude_deg, vib.roll_amplitude_deg]) / n
        self.reset()

    def reset(self) -> None:
        self._frame = -1
        self._speed: float | None = None
        self._theta = 0.0      # suspension pitch (deg)
        self._omega = 0.0      # its rate (deg/s)

    def vibration_deg(self, t: np.ndarray | float) -> np.ndarray:
        """(..., 2) pitch and roll vibration (deg) at time(s) ``t`` (s)."""
        t = np.asarray(t, dtype=float)[..., None, None]
        return (self._amp[:, None] * np.sin(2 * math.pi * self._f * t + self._phi)).sum(axis=-1)

    def _suspension(self, speed: float) -> float:
        """Advance the spring-damper by one frame, driven by the acceleration since the last frame."""
        s = self.motion.suspension
        if self._speed is None or s.pitch_deg_per_mps2 == 0:
            self._speed = speed
            return self._theta
        a = float(np.clip((speed - self._speed) * self.fps, -ACCEL_LIMIT_MPS2, ACCEL_LIMIT_MPS2))
        self._speed = speed
        target = -s.pitch_deg_per_mps2 * a
        w = 2 * math.pi * s.natural_hz
        h = 1.0 / (self.fps * SUSPENSION_SUBSTEPS)
        for _ in range(SUSPENSION_SUBSTEPS):     # semi-implicit Euler
            self._omega += h * (w * w * (target - self._theta) - 2 * s.damping_ratio * w * self._omega)
            self._theta += h * self._omega
        return self._theta

    def pose_deg(self, frame: int, ego_speed: float) -> tuple[float, float]:
        """(pitch, roll) offsets from the nominal calibration (deg) of ``frame``; frames must come in order."""
        if frame != self._frame + 1:
            raise ValueError(f"camera motion: frame {frame} after frame {self._frame} (frames must come in order)")
        self._frame = frame
        susp = self._suspension(float(ego_speed))
        vib = self.vibration_deg(frame / self.fps)
        m = self.motion.mount
        return m.pitch_deg + susp + float(vib[0]), m.roll_deg + float(vib[1])

    def camera(self, frame: int, ego_speed: float) -> CameraModel:
        """The true camera of ``frame`` (nominal intrinsics and mounting, turned by :meth:`pose_deg`)."""
        dp, dr = self.pose_deg(frame, ego_speed)
        return replace(self.nominal, pitch_rad=self.nominal.pitch_rad + math.radians(dp),
                       roll_rad=self.nominal.roll_rad + math.radians(dr))


def pose_record(true: CameraModel, nominal: CameraModel) -> dict:
    """The ``camera`` entry of a ground-truth record: the frame's true pose."""
    return {"pitch_rad": true.pitch_rad, "roll_rad": true.roll_rad, "horizon_row": true.horizon_row,
            "pitch_offset_rad": true.pitch_rad - nominal.pitch_rad,
            "horizon_offset_px": true.horizon_row - nominal.horizon_row}
