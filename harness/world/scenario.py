"""Scenario files: YAML validated by pydantic models (unknown keys rejected).

Units: metres, seconds, m/s, m/s^2, degrees where a field name says ``_deg``.
Lanes are indexed 0..lanes-1 from the leftmost lane; a vehicle's ``lane`` in a
scenario is *relative to the ego lane* (-1 = one lane to the left, +1 = right).
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Annotated, Any, Literal, Union

from pydantic import BaseModel, ConfigDict, Field, FiniteFloat, field_validator, model_serializer, model_validator

from harness.world.camera_motion import CameraMotion
from harness.world.config_io import SAFE_NAME, Seed, validate_config
from harness.world.road_plan import MAX_TURN_RAD, MIN_RADIUS_M
from harness.world.road_profile import MAX_GRADE

from monorarp.app.common_options import check_frames, frames_within
from monorarp.core.camera import CameraError, CameraModel
from monorarp.core.errors import UserError
from monorarp.core.readers import read_yaml


class ScenarioError(UserError, ValueError):
    """A scenario file that cannot be read or is invalid; the message names file, field and reason."""


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Markings(_Model):
    """Painted lane lines (US defaults: 3.05 m stripes every 12.19 m, 0.15 m wide)."""

    stripe_length_m: float = Field(3.05, gt=0)
    period_m: float = Field(12.19, gt=0)
    width_m: float = Field(0.15, gt=0, le=1.0)
    solid_edges: bool = True

    @model_validator(mode="after")
    def _stripe_fits(self) -> "Markings":
        if self.stripe_length_m >= self.period_m:
            raise ValueError("stripe_length_m must be shorter than period_m")
        return self


class GradeChange(_Model):
    """From ``start_m`` (road x ahead of the camera at t = 0, the origin of ``distance_m``) the grade
    turns to ``grade`` (rise/run, + uphill) along a parabolic vertical curve ``transition_m`` long
    (:mod:`harness.world.road_profile`)."""

    start_m: float = Field(ge=-1000, le=5000)
    grade: float = Field(ge=-MAX_GRADE, le=MAX_GRADE, description="rise/run after the change; + uphill")
    transition_m: float = Field(0.0, ge=0, le=2000, description="length of the vertical curve, m")


class Curve(_Model):
    """From ``start_m`` (road x ahead of the camera at t = 0, the origin of ``distance_m``) the road
    turns ``direction`` along a clothoid ``transition_m`` long into an arc of ``radius_m`` for
    ``length_m``, then a clothoid of ``transition_m`` back to straight (:mod:`harness.world.road_plan`)."""

    start_m: float = Field(ge=-1000, le=5000)
    radius_m: float = Field(ge=MIN_RADIUS_M, le=100000, description="radius of the arc, m")
    direction: Literal["left", "right"]
    length_m: float = Field(0.0, ge=0, le=5000, description="length of the arc at radius_m, m")
    transition_m: float = Field(0.0, ge=0, le=2000, description="length of each clothoid, m")

    @property
    def end_m(self) -> float:
        return self.start_m + 2 * self.transition_m + self.length_m

    @property
    def turn_rad(self) -> float:
        """Signed heading change (rad, + right)."""
        return (1 if self.direction == "right" else -1) * (self.transition_m + self.length_m) / self.radius_m


#: The narrowest parking strip (m): the widest parked body (a van, 2.07 m, and its mirrors) and a margin.
MIN_PARKING_STRIP_M = 2.3
#: Smallest angle of angled parking bays (deg), and the small car an angled strip must hold (length, width, m).
MIN_BAY_ANGLE_DEG, BAY_CAR_M = 30.0, (3.6, 1.6)


class Street(_Model):
    """An urban street (:mod:`harness.simulation.parking`, :mod:`harness.render.street`): the shoulders are
    parking strips (asphalt, ``road.shoulder_width_m`` wide beyond the outer edge lines) ending at a kerb,
    a pavement beyond it, then the frontage (houses, walls, hedges, fences) of the realistic look."""

    parking: Literal["none", "right", "both"] = Field("both", description="which parking strips hold parked cars")
    parked_per_100m: float = Field(10.0, ge=0, le=18, description="parked cars per 100 m of each strip")
    facing_traffic_share: float = Field(0.85, ge=0, le=1, description=(
        "share of parked cars facing their side's direction of travel (right: along +x, left: against it); "
        "the others face the other way (their fronts towards the camera on the right)"))
    pavement_m: float = Field(2.5, ge=0.5, le=8.0, description="width of each pavement beyond the kerb, m")
    bay_angle_deg: float = Field(0.0, ge=0, le=90, description=(
        "angle of the parked cars' long axis to the kerb, deg: 0 parallel parking (nose to tail), 30-90 angled "
        "or perpendicular bays (side by side, seen from the side; the strip must be deep enough)"))

    @model_validator(mode="after")
    def _bay_angle(self) -> "Street":
        if 0.0 < self.bay_angle_deg < MIN_BAY_ANGLE_DEG:
            raise ValueError(f"bay_angle_deg: {self.bay_angle_deg} deg; 0 (parallel) or "
                             f"{MIN_BAY_ANGLE_DEG:g}-90 (angled bays)")
        return self

    @model_serializer(mode="wrap")
    def _dump(self, handler):
        data = handler(self)
        if self.bay_angle_deg == 0.0:   # parallel parking dumps as before the field existed
            data.pop("bay_angle_deg", None)
        return data

    def strip_needed_m(self) -> float:
        """The shallowest parking strip that holds a small car (3.6 m x 1.6 m) at ``bay_angle_deg`` (m)."""
        if self.bay_angle_deg == 0.0:
            return MIN_PARKING_STRIP_M
        a = math.radians(self.bay_angle_deg)
        return round(BAY_CAR_M[0] * math.sin(a) + BAY_CAR_M[1] * math.cos(a) + 0.1, 2)


class Road(_Model):
    lanes: int = Field(3, ge=1, le=8)
    lane_width_m: float = Field(4.0, ge=2.5, le=6.0)
    length_m: float = Field(3000.0, ge=200)
    shoulder_width_m: float = Field(2.5, ge=0, le=10)
    speed_limit_mps: float = Field(33.0, gt=0, le=60)
    markings: Markings = Markings()
    profile: list[GradeChange] = Field([], description="vertical profile: grade changes in order; empty: level")
    curves: list[Curve] = Field([], description="horizontal curves in order; empty: straight")
    street: Street | None = Field(None, description=(
        "an urban street: parked cars on the shoulders (parking strips), kerbs, pavements, frontages; "
        "null: a motorway (hard shoulders, verges, roadside furniture)"))

    @model_validator(mode="after")
    def _ordered(self) -> "Road":
        for i in range(1, len(self.profile)):
            prev, seg = self.profile[i - 1], self.profile[i]
            if seg.start_m < prev.start_m + prev.transition_m:
                raise ValueError(f"profile.{i}.start_m: {seg.start_m} m lies before the end of the previous "
                                 f"change's transition ({prev.start_m + prev.transition_m} m)")
        heading = 0.0
        for i, seg in enumerate(self.curves):
            if i and seg.start_m < self.curves[i - 1].end_m:
                raise ValueError(f"curves.{i}.start_m: {seg.start_m} m lies before the end of the previous "
                                 f"curve ({self.curves[i - 1].end_m} m)")
            heading += seg.turn_rad
            if abs(heading) > MAX_TURN_RAD + 1e-9:
                raise ValueError(f"curves.{i}: the road would turn {math.degrees(heading):.0f} deg from its "
                                 f"start (at most {math.degrees(MAX_TURN_RAD):.0f})")
        return self

    @model_validator(mode="after")
    def _parking_room(self) -> "Road":
        st = self.street
        if st is not None and st.parking != "none" and self.shoulder_width_m < st.strip_needed_m():
            holds = ("the widest parked van with its mirrors" if st.bay_angle_deg == 0.0 else
                     f"a {BAY_CAR_M[0]} m x {BAY_CAR_M[1]} m car at street.bay_angle_deg {st.bay_angle_deg:g}")
            raise ValueError(f"shoulder_width_m: {self.shoulder_width_m} m is too narrow a parking strip for "
                             f"street.parking {st.parking!r} (at least {st.strip_needed_m()} m: {holds})")
        return self

    @model_serializer(mode="wrap")
    def _dump(self, handler):
        data = handler(self)
        if not self.profile:   # a level road dumps as before the field existed
            data.pop("profile", None)
        if not self.curves:    # so does a straight one
            data.pop("curves", None)
        if self.street is None:   # and a motorway
            data.pop("street", None)
        return data


class IDMParams(_Model):
    """Intelligent Driver Model parameters (highway-env's IDMVehicle defaults)."""

    a_max: float = Field(3.0, gt=0, le=10, description="comfortable acceleration, m/s^2")
    b_comfort: float = Field(5.0, gt=0, le=10, description="comfortable deceleration (positive), m/s^2")
    distance_wanted_m: float = Field(10.0, ge=0, le=50)
    time_wanted_s: float = Field(1.5, ge=0, le=5)
    delta: float = Field(4.0, gt=0, le=10)


class MOBILParams(_Model):
    politeness: float = Field(0.0, ge=0, le=1)
    min_acc_gain: float = Field(0.2, ge=0, le=5)
    max_braking_imposed: float = Field(2.0, ge=0, le=10)
    lane_change_delay_s: float = Field(1.0, ge=0, le=10)


class Traffic(_Model):
    """Random IDM/MOBIL traffic placed by highway-env around the ego."""

    vehicles_count: int = Field(10, ge=0, le=200)
    density: float = Field(1.0, gt=0, le=5)
    speed_range_mps: tuple[float, float] = (20.0, 30.0)
    lane_changes: bool = True
    idm: IDMParams = IDMParams()
    mobil: MOBILParams = MOBILParams()
    warmup_s: float = Field(0.0, ge=0, le=60, description=(
        "the world simulated this long (s) before frame 0, so that the braking wave of the placement is "
        "over when the camera starts (placed vehicles' distance_m hold at its start); 0: frame 0 is the placement"))
    fleet: Literal["none", "mixed"] = Field("none", description=(
        "none: every traffic vehicle is highway-env's 5 m x 2 m car; mixed: each gets a body type and footprint "
        "drawn from motorway fleet shares (harness.world.fleet), seeded by the scenario seed and its id"))

    @model_validator(mode="after")
    def _range(self) -> "Traffic":
        lo, hi = self.speed_range_mps
        if not 0 <= lo <= hi <= 60:
            raise ValueError("speed_range_mps must be [low, high] with 0 <= low <= high <= 60")
        return self

    @model_serializer(mode="wrap")
    def _dump(self, handler):
        data = handler(self)
        if not self.warmup_s:   # no warm-up dumps as before the field existed
            data.pop("warmup_s", None)
        if self.fleet == "none":   # so does the default fleet
            data.pop("fleet", None)
        return data


Behaviour = Literal["idm", "constant_speed", "stationary"]


class Ego(_Model):
    lane: int = Field(1, ge=0, description="absolute lane index, 0 = leftmost")
    speed_mps: float = Field(25.0, ge=0, le=60)
    behaviour: Literal["idm", "constant_speed"] = "constant_speed"
    lane_changes: bool = False


class PlacedVehicle(_Model):
    """A named vehicle placed relative to the ego at t = 0.

    ``distance_m`` is the longitudinal distance from the camera to the vehicle's
    rear face (what ``d_long`` measures); negative places it behind.
    """

    name: str = Field(pattern=r"^[A-Za-z_][A-Za-z0-9_\-]*$")
    lane: int = Field(0, ge=-7, le=7, description="lane relative to the ego's")
    distance_m: float = Field(ge=-200, le=500)
    speed_mps: float = Field(0.0, ge=0, le=60)
    behaviour: Behaviour = "idm"
    lane_changes: bool = False
    length_m: float | None = Field(None, ge=3.0, le=20.0, description=(
        "m; absent: 5.0, or with a body drawn from the type's typical dimensions (harness.world.fleet)"))
    width_m: float | None = Field(None, ge=1.4, le=3.0, description="m, mirrors included; absent: as length_m")
    lateral_offset_m: float = Field(0.0, ge=-2.0, le=2.0, description=(
        "offset of its centre from its lane's centre line, + right; held until a cut_in moves it"))
    body: Literal["hatchback", "saloon", "estate", "suv", "van", "pickup", "box_truck", "artic", "bus"] | None = Field(
        None, description="body type (harness.world.vehicles.BODY_TYPES); null: the footprint decides the shape")

    @model_validator(mode="before")
    @classmethod
    def _default_size(cls, data: Any) -> Any:
        """Without a body an absent (or null) size is highway-env's 5 m x 2 m, as before the body existed."""
        if isinstance(data, dict) and data.get("body") is None:
            data = {**data, "length_m": 5.0 if data.get("length_m") is None else data["length_m"],
                    "width_m": 2.0 if data.get("width_m") is None else data["width_m"]}
        return data

    @model_serializer(mode="wrap")
    def _dump(self, handler):
        data = handler(self)
        if self.body is None:   # a vehicle without a body dumps as before the field existed
            data.pop("body", None)
        return data


class BrakeEvent(_Model):
    type: Literal["brake"]
    vehicle: str
    at_s: float = Field(ge=0)
    decel_mps2: float = Field(gt=0, le=12)
    until_speed_mps: float = Field(0.0, ge=0)


class CutInEvent(_Model):
    """At ``at_s`` the vehicle, in a lane adjacent to the ego's, steers into the ego's lane.

    Its initial distance is chosen so that at ``at_s`` its rear is ``gap_m``
    ahead of the camera if both keep their initial speeds.
    """

    type: Literal["cut_in"]
    vehicle: str
    at_s: float = Field(ge=0)
    gap_m: float = Field(gt=0, le=200)


class SpeedChangeEvent(_Model):
    type: Literal["speed_change"]
    vehicle: str = Field(description="a placed vehicle's name or 'ego'")
    at_s: float = Field(ge=0)
    target_speed_mps: float = Field(ge=0, le=60)


Event = Annotated[Union[BrakeEvent, CutInEvent, SpeedChangeEvent], Field(discriminator="type")]


class Camera(_Model):
    """Either ``focal_px`` or ``hfov_deg``; principal point at the image centre."""

    width: int = Field(640, ge=64, le=7680)
    height: int = Field(360, ge=48, le=4320)
    focal_px: float | None = Field(None, gt=0)
    hfov_deg: float | None = Field(70.0, gt=1, lt=179)
    height_m: float = Field(1.3, gt=0.2, le=5.0)
    pitch_deg: float = Field(2.0, ge=-30, le=30, description="positive tilts the camera down")
    lateral_offset_m: float = Field(0.0, ge=-2, le=2)
    forward_offset_m: float = Field(0.5, ge=-3, le=3, description="from the ego vehicle's centre")
    distortion: tuple[FiniteFloat, FiniteFloat, FiniteFloat, FiniteFloat, FiniteFloat] | None = Field(None, description=(
        "OpenCV lens distortion [k1, k2, p1, p2, k3] (monorarp.core.distortion); null: a pinhole lens"))

    def model(self) -> CameraModel:
        """The shared :class:`CameraModel` this spec describes."""
        mount = dict(height_m=self.height_m, pitch_rad=math.radians(self.pitch_deg),
                     lateral_offset_m=self.lateral_offset_m, forward_offset_m=self.forward_offset_m)
        if self.distortion is not None:
            mount["distortion"] = tuple(self.distortion)
        if self.focal_px is not None:
            return CameraModel(self.width, self.height, self.focal_px, self.focal_px,
                               (self.width - 1) / 2, (self.height - 1) / 2, **mount)
        return CameraModel.from_fov(self.width, self.height, self.hfov_deg, **mount)

    @model_validator(mode="after")
    def _possible(self) -> "Camera":
        if self.focal_px is None and self.hfov_deg is None:
            raise ValueError("give focal_px or hfov_deg (both are null)")
        try:
            self.model()
        except CameraError as e:
            raise ValueError(str(e)) from None
        return self

    @model_serializer(mode="wrap")
    def _dump(self, handler):
        data = handler(self)
        if self.distortion is None:   # a pinhole camera dumps as before the field existed
            data.pop("distortion", None)
        return data


class Render(_Model):
    palette_seed: Seed = 0
    light_direction: tuple[FiniteFloat, FiniteFloat, FiniteFloat] = Field((-0.4, 0.3, -1.0), description="direction the light travels, in the road frame (x along the road, y left, z up)")
    light_intensity: float = Field(3.0, gt=0, le=20)
    noise_std: float = Field(0.0, ge=0, le=50, description="Gaussian sensor noise, 8-bit levels")
    blur_px: float = Field(0.0, ge=0, le=10, description="Gaussian blur sigma, pixels")
    look: Literal["simple", "realistic"] = Field("simple", description=(
        "simple: flat-shaded boxes under a uniform sky; realistic: textured road, roadside, sky, shadows, "
        "sensor model, drawn from look_family by look_seed (harness.render.look)"))
    look_family: Literal["train", "heldout"] = Field("train", description=(
        "the randomisation family of a realistic look: train, or the disjoint held-out one"))
    look_seed: Seed | None = Field(None, description="seed of the realistic look; null: the scenario's seed")

    @model_validator(mode="after")
    def _light(self) -> "Render":
        if math.hypot(*self.light_direction) < 1e-6:
            raise ValueError("light_direction must be non-zero")
        return self


class Conditions(_Model):
    """Light, weather and lens (:mod:`harness.render.effects`). Absent: a clear day, no lens effect."""

    time_of_day: Literal["day", "low_sun", "dusk", "night"] = Field("day", description=(
        "day: render.light_*; low_sun: sun 6 deg up ahead; dusk: sky light only; night: no ambient light"))
    fog_visibility_m: float | None = Field(None, gt=0, le=100000, description=(
        "visibility V, m: contrast exp(-3.912 d / V) at range d; null: no fog"))
    rain: float = Field(0.0, ge=0, le=1, description="0 dry .. 1 heavy: streaks, wet road, extinction")
    headlights: bool = Field(True, description="ego low beams at dusk and night")
    exposure_s: float = Field(0.0, ge=0, le=0.05, description="shutter open time (motion blur), s")
    readout_s: float = Field(0.0, ge=0, le=0.05, description="rolling-shutter readout, top row to bottom row, s")
    jpeg_quality: int | None = Field(None, ge=1, le=100, description="JPEG quality 1..100; null: none")


class Scenario(_Model):
    name: str = Field(max_length=80, description="also the default output directory runs/NAME")
    seed: Seed = 0
    duration_s: float = Field(10.0, gt=0, le=3600)
    fps: float = Field(15.0, ge=1, le=120)
    road: Road = Road()
    traffic: Traffic = Traffic()
    ego: Ego = Ego()
    vehicles: list[PlacedVehicle] = []
    events: list[Event] = []
    camera: Camera = Camera()
    render: Render = Render()
    camera_motion: CameraMotion | None = Field(None, description=(
        "pitch/roll of the camera relative to the road per frame (harness.world.camera_motion); null: none"))
    conditions: Conditions | None = None
    end_on_contact_s: float | None = Field(None, ge=0, le=10, description=(
        "end the run this long (s) after the ego's first contact (crash flag); null: run the whole duration"))

    @property
    def n_frames(self) -> int:
        return int(round(self.duration_s * self.fps))

    @field_validator("name")
    @classmethod
    def _safe_name(cls, name: str) -> str:
        if not re.fullmatch(SAFE_NAME, name):   # not re.match: its "$" matches before a final newline
            raise ValueError(f"{name!r} is not a plain name (letters, digits, _ . + -, not starting with '.'; "
                             "it names the output directory runs/NAME)")
        return name

    @model_validator(mode="after")
    def _consistent(self) -> "Scenario":
        if self.ego.lane >= self.road.lanes:
            raise ValueError(f"ego.lane {self.ego.lane} does not exist on a {self.road.lanes}-lane road")
        if self.render.look == "realistic" and self.conditions is not None and self.conditions.time_of_day != "day":
            raise ValueError(f"render.look realistic is a daylight look; conditions.time_of_day "
                             f"{self.conditions.time_of_day!r} needs render.look simple")
        if self.camera_motion is not None:
            self.camera_motion.check(self.camera.model(), self.fps)
        if self.traffic.warmup_s and self.events:
            raise ValueError("traffic.warmup_s: a warm-up needs a scenario without events (their times and "
                             "cut-in gaps are set from the placement)")
        names = [v.name for v in self.vehicles]
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            raise ValueError(f"vehicles: duplicate names {sorted(dup)}")
        for i, v in enumerate(self.vehicles):
            lane = self.ego.lane + v.lane
            if not 0 <= lane < self.road.lanes:
                raise ValueError(f"vehicles.{i}.lane: relative lane {v.lane} from ego lane {self.ego.lane} is off the road")
        for i, e in enumerate(self.events):
            if e.vehicle != "ego" and e.vehicle not in names:
                raise ValueError(f"events.{i}.vehicle: no placed vehicle named {e.vehicle!r}")
            if e.vehicle == "ego" and not isinstance(e, SpeedChangeEvent):
                raise ValueError(f"events.{i}: only speed_change may target the ego")
            if isinstance(e, CutInEvent):
                v = self.vehicles[names.index(e.vehicle)]
                if abs(v.lane) != 1:
                    raise ValueError(f"events.{i}: cut_in vehicle {e.vehicle!r} must start in a lane adjacent to the ego's")
        return self


def frames_to_simulate(scenario: Scenario, frames: int | None, source: str | Path, verb: str = "render") -> int:
    """``--frames N`` checked against ``scenario`` (1 .. duration_s * fps; None: all); :class:`UserError` otherwise."""
    check_frames(frames)
    if scenario.n_frames <= 0:
        raise UserError(f"{source}: duration_s * fps gives no frames")
    return frames_within(frames, scenario.n_frames, "scenario's",
                         f" (duration_s * fps); raise duration_s in {source} to {verb} more")


def parse_scenario(data: Any, source: str | Path = "<scenario>") -> Scenario:
    """Validate an already-loaded mapping (e.g. after a sweep applied overrides)."""
    return validate_config(Scenario, data, source, ScenarioError, "scenario")


def load_scenario_dict(path: str | Path) -> dict:
    """Read a scenario YAML into a plain dict (no validation)."""
    return read_yaml(path, "scenario", ScenarioError)


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario file; raises :class:`ScenarioError` naming file, field, reason."""
    return parse_scenario(load_scenario_dict(path), path)
