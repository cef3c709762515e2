"""The camera between the scene's light and the 8-bit frame: the sensor of the ``realistic`` look.

:func:`apply_camera` takes the renderer's colour pass (display-referred scene radiance, encoded with
the renderer's pure 2.2 gamma, :mod:`harness.render.shading`) and models, in linear light and in
this order: white-balance error, exposure, defocus, vignetting, shot + read noise, a filmic tone
curve, the gamma encoding and the codec (per-frame JPEG, 4:2:0 chroma).

Units: the linear signal ``S`` is in 8-bit levels of linear light, 255 = the full scale of the
input (before exposure and gains), so the noise parameters of
:class:`harness.render.look.SensorLook` read as a raw sensor's: variance
``shot_noise * S + read_noise ** 2`` (levels^2). Pixel coordinates: OpenCV (x right, y down,
pixel centres at integers); vignetting is radial about the image centre.

Speed: every per-pixel step is one cv2/numpy pass over per-thread buffers (fresh multi-MB arrays
per frame cost more in page faults than the maths): one 3-channel LUT (decode x gains), a
separable blur, one product (vignetting), the noise (16-bit uniforms from the generator's raw
output through a Gaussian inverse-CDF table) and one 16-bit LUT (tone curve + encoding, cached
per contrast), then JPEG. A 640x360 frame with every step on costs ~10 ms of one core of a
shared 2-vCPU EPYC VM (median; 8 ms at best), of which the JPEG round trip is ~1.7 ms.

:func:`encode_h264_roundtrip` is the clip-level alternative to the per-frame JPEG: real H.264
(libx264 via imageio-ffmpeg), single-threaded and bit-exact, for a whole clip at once.
"""

from __future__ import annotations

import functools
import math
import subprocess
import tempfile
import threading
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np
from scipy.special import ndtri

from harness.render.look import SensorLook

GAMMA = 2.2                 # the renderer's encoding (shading.py, effects.py)
MID_GREY = 0.18             # linear; the tone curve's pivot: f(0.18) = 0.18, slope = contrast there
KNEE = 0.7                  # linear display level where the shoulder starts (sRGB 217 of 255)
MIN_DEFOCUS_PX = 0.3        # defocus below this sigma (px) is skipped
_TONE_BINS = 65536          # entries of the tone LUT (indexed by the 16-bit rounded linear signal)
_RNG_TAG = 0xCA3E5A         # keeps this noise stream apart from harness.render.sensor's

#: uint8 code -> linear light 0..1 (the renderer's 2.2 gamma)
_DECODE = ((np.arange(256) / 255.0) ** GAMMA).astype(np.float64)


# ---------------------------------------------------------------- closed forms
def tone_curve(x: np.ndarray | float, contrast: float) -> np.ndarray:
    """Filmic tone curve: linear scene level ``x`` (1 = input full scale, may exceed 1) -> linear display 0..1.

    ``p = 0.18 (x / 0.18) ** contrast`` (a power about mid-grey: slope ``contrast`` there in
    linear, in log-log and in gamma-encoded terms alike, since f(0.18) = 0.18; for contrast > 1 a
    toe that deepens the shadows), then a C1 exponential shoulder above :data:`KNEE`:
    ``1 - (1 - KNEE) exp(-(p - KNEE) / (1 - KNEE))``, so highlights roll off towards 1 instead of
    clipping. f(0) = 0, strictly increasing, the identity on [0, KNEE] at contrast 1 (input 255
    comes out at ~242 of 255).
    """
    x = np.maximum(np.asarray(x, dtype=np.float64), 0.0)
    p = MID_GREY * (x / MID_GREY) ** float(contrast)
    over = np.maximum(p - KNEE, 0.0)
    return np.where(p <= KNEE, p, 1.0 - (1.0 - KNEE) * np.exp(-over / (1.0 - KNEE)))


def vignette_field(height: int, width: int, vignetting: float) -> np.ndarray:
    """(H, W) float32 relative illumination of a cos^4 falloff, 1 at the centre, ``1 - vignetting`` at the corners.

    ``V(r) = cos^4(atan(r tan t_c)) = (1 + (r tan t_c)^2)^-2`` with ``r`` the distance from the
    image centre ((W-1)/2, (H-1)/2) over that of the corner pixel centres, and ``t_c`` the corner
    field angle for which ``cos^4 t_c = 1 - vignetting``.
    """
    return _vignette(int(height), int(width), float(vignetting))[..., 0]


@functools.lru_cache(maxsize=16)
def _vignette(height: int, width: int, vignetting: float) -> np.ndarray:
    """(H, W, 3) float32, read-only: :func:`vignette_field` in three channels."""
    if not 0.0 <= vignetting < 1.0:
        raise ValueError(f"vignetting {vignetting} not in [0, 1)")
    cx, cy = (width - 1) / 2.0, (height - 1) / 2.0
    x = (np.arange(width) - cx)[None, :]
    y = (np.arange(height) - cy)[:, None]
    r2 = (x * x + y * y) / max(cx * cx + cy * cy, 1e-12)
    tan2 = (1.0 - vignetting) ** -0.5 - 1.0                 # tan^2 t_c = 1 / cos^2 t_c - 1
    field = (1.0 / (1.0 + r2 * tan2) ** 2).astype(np.float32)
    out = cv2.merge([field, field, field])
    out.setflags(write=False)
    return out


# ---------------------------------------------------------------- tables
@functools.lru_cache(maxsize=64)
def _tone_lut(contrast: float) -> tuple[np.ndarray, float]:
    """(LUT, q): ``LUT[round(S * q)]`` is the 8-bit output of linear signal ``S`` (levels), saturating above.

    The domain ends where the output first rounds to 255, so the top entry (and every index it
    saturates to) is 255 and the resolution is as fine as 16 bits allow (0.01 level at contrast 1).
    """
    if contrast <= 0:
        raise ValueError(f"contrast {contrast} must be > 0")
    top = (254.5 / 255.0) ** GAMMA                                   # display level that rounds to 255
    p_top = KNEE + (1.0 - KNEE) * math.log((1.0 - KNEE) / (1.0 - top)) + 1e-3
    s_max = 255.0 * MID_GREY * (p_top / MID_GREY) ** (1.0 / contrast)
    q = (_TONE_BINS - 1) / s_max
    x = np.arange(_TONE_BINS) / q / 255.0
    lut = np.rint(255.0 * tone_curve(x, contrast) ** (1.0 / GAMMA)).astype(np.uint8)
    lut.setflags(write=False)
    return lut, q


@functools.lru_cache(maxsize=1)
def _normal_quantiles() -> np.ndarray:
    """(65536,) float32: standard normal quantiles at (k + 1/2) / 65536, rescaled to unit variance.

    A 16-bit uniform through this table is a Gaussian sample (inverse-CDF sampling; tails cut at
    4.3 sigma, the rescale of 1.0002 restores the variance), ~8x cheaper than ``standard_normal``.
    """
    z = ndtri((np.arange(65536) + 0.5) / 65536.0)
    z /= np.sqrt(np.mean(z * z))
    out = z.astype(np.float32)
    out.setflags(write=False)
    return out


def _normals(seed: int, frame: int, out: np.ndarray) -> np.ndarray:
    """Fill float32 ``out`` with independent standard normals of (``seed``, ``frame``) (numpy default_rng, PCG64)."""
    rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, int(frame) & 0xFFFFFFFF, _RNG_TAG])
    flat = out.reshape(-1)
    u16 = rng.bit_generator.random_raw((flat.size + 3) // 4).view(np.uint16)[:flat.size]
    np.take(_normal_quantiles(), u16, out=flat, mode="clip")
    return out


class _Workspace:
    """Per-thread buffers of one frame size: fresh multi-MB arrays per frame cost more in page faults than the maths."""

    def __init__(self, height: int, width: int) -> None:
        self.shape = (height, width)
        self.lin = np.empty((height, width, 3), np.float32)
        self.blur = np.empty((height, width, 3), np.float32)
        self.std = np.empty((height, width * 3), np.float32)
        self.z = np.empty((height, width * 3), np.float32)
        self.idx = np.empty((height, width * 3), np.uint16)
        self.out = np.empty((height, width * 3), np.uint8)


_local = threading.local()


def _workspace(height: int, width: int) -> _Workspace:
    ws = getattr(_local, "ws", None)
    if ws is None or ws.shape != (height, width):
        ws = _local.ws = _Workspace(height, width)
    return ws


# ---------------------------------------------------------------- codec
def encode_jpeg(bgr: np.ndarray, quality: int) -> bytes:
    """Baseline JPEG of uint8 BGR ``bgr`` at ``quality`` (1..100) with 4:2:0 chroma.

    cv2 builds without ``IMWRITE_JPEG_SAMPLING_FACTOR`` still give 4:2:0: libjpeg's
    ``jpeg_set_defaults`` samples luma 2x2 (the test reads the frame header to check it).
    """
    params = [cv2.IMWRITE_JPEG_QUALITY, int(quality)]
    if hasattr(cv2, "IMWRITE_JPEG_SAMPLING_FACTOR"):
        params += [cv2.IMWRITE_JPEG_SAMPLING_FACTOR, cv2.IMWRITE_JPEG_SAMPLING_FACTOR_420]
    ok, buf = cv2.imencode(".jpg", bgr, params)
    if not ok:
        raise RuntimeError("JPEG encoding failed")
    return buf.tobytes()


def jpeg_roundtrip(bgr: np.ndarray, quality: int) -> np.ndarray:
    """uint8 BGR through JPEG at ``quality`` (4:2:0) and back (blocking, ringing, chroma loss)."""
    return cv2.imdecode(np.frombuffer(encode_jpeg(bgr, quality), np.uint8), cv2.IMREAD_COLOR)


# ---------------------------------------------------------------- the chain
def _check(bgr: np.ndarray, sensor: SensorLook) -> None:
    if bgr.dtype != np.uint8 or bgr.ndim != 3 or bgr.shape[2] != 3:
        raise ValueError(f"expected (H, W, 3) uint8 BGR, got {bgr.shape} {bgr.dtype}")
    if sensor.shot_noise < 0 or sensor.read_noise < 0 or min(sensor.wb_gains) <= 0:
        raise ValueError(f"noise must be >= 0 and gains > 0: {sensor}")
    if not 1 <= sensor.jpeg_quality <= 100:
        raise ValueError(f"jpeg_quality {sensor.jpeg_quality} not in 1..100")


def _linear(bgr: np.ndarray, sensor: SensorLook, seed: int, frame: int, ws: _Workspace
            ) -> tuple[np.ndarray, np.ndarray | None]:
    """Steps 1-4 of :func:`apply_camera` in ``ws``: the clean linear signal and its noise (levels), each
    (H, W * 3) float32 (noise None when off); the signal is their sum (:func:`apply_camera` adds them
    while it quantises)."""
    h, w, _ = bgr.shape
    gains = np.asarray(sensor.wb_gains, dtype=np.float64)[::-1] * 2.0 ** float(sensor.exposure_ev)   # B, G, R
    lut = (255.0 * _DECODE[:, None] * gains[None, :]).astype(np.float32).reshape(1, 256, 3)
    s = cv2.LUT(np.ascontiguousarray(bgr), lut, dst=ws.lin)
    sigma = float(sensor.defocus_px)
    if sigma >= MIN_DEFOCUS_PX:
        k = 2 * math.ceil(3.0 * sigma) + 1
        s = cv2.GaussianBlur(s, (k, k), sigma, dst=ws.blur, borderType=cv2.BORDER_REFLECT101)
    if sensor.vignetting > 0:
        np.multiply(s, _vignette(h, w, float(sensor.vignetting)), out=s)
    flat = s.reshape(h, w * 3)                      # elementwise from here: one channel for cv2
    shot, read = float(sensor.shot_noise), float(sensor.read_noise)
    if shot == 0 and read == 0:
        return flat, None
    noise = cv2.addWeighted(flat, shot, flat, 0.0, read * read, dst=ws.std)   # the variance
    cv2.sqrt(noise, dst=noise)
    noise *= _normals(seed, frame, ws.z)
    return flat, noise


def linear_signal(bgr: np.ndarray, sensor: SensorLook, seed: int, frame: int) -> np.ndarray:
    """(H, W, 3) float32 linear signal (levels, 255 = input full scale) after steps 1-4 of :func:`apply_camera`.

    Not clipped: noise may take it below 0 (the tone stage clips black).
    """
    _check(bgr, sensor)
    h, w, _ = bgr.shape
    flat, noise = _linear(bgr, sensor, seed, frame, _workspace(h, w))
    out = flat.copy() if noise is None else flat + noise
    return out.reshape(h, w, 3)


def apply_camera(bgr: np.ndarray, sensor: SensorLook, seed: int, frame: int) -> np.ndarray:
    """The dashcam's view of the colour pass ``bgr`` ((H, W, 3) uint8 BGR) -> (H, W, 3) uint8 BGR.

    In linear light ``S`` (levels, see the module docstring):

    1. white-balance error and exposure: ``S_c = 255 lin(bgr_c) * wb_gains_c * 2 ** exposure_ev``
       (``wb_gains`` in R, G, B order);
    2. defocus: Gaussian blur of sigma ``defocus_px`` (px, kernel to 3 sigma; skipped below
       :data:`MIN_DEFOCUS_PX`);
    3. vignetting: times :func:`vignette_field`;
    4. noise: ``S + sqrt(shot_noise S + read_noise^2) z``, ``z`` standard normal, independent per
       pixel and channel, drawn from ``default_rng([seed, frame, tag])`` (the Gaussian
       approximation of Poisson-Gaussian noise);
    5. :func:`tone_curve` of ``S / 255`` at ``contrast`` (black clips at 0), encoded with gamma
       1/2.2 to 8 bits (through a 16-bit LUT of ``S``);
    6. the codec: JPEG at ``jpeg_quality`` with 4:2:0 chroma (:func:`jpeg_roundtrip`).

    Why per-frame JPEG for a dashcam's H.264: at a dashcam's bit rates an H.264 frame shows the
    artefacts a JPEG of similar quality does: blocking from the quantised block transform (4x4/8x8
    against JPEG's 8x8), ringing at edges, smeared 4:2:0 chroma. What JPEG lacks is the
    inter-frame part (motion-compensated drift, keyframe pumping, smearing of fast motion); that
    needs the whole clip (:func:`encode_h264_roundtrip`), while a frame here stays a function of
    its own (seed, frame), as rendering frames in any order requires.

    Deterministic: the same inputs give the same bytes.
    """
    _check(bgr, sensor)
    h, w, _ = bgr.shape
    ws = _workspace(h, w)
    flat, noise = _linear(bgr, sensor, seed, frame, ws)
    tone, q = _tone_lut(float(sensor.contrast))
    if noise is None:                               # round(q S) to 16 bits; negatives -> 0 (black clip)
        idx = cv2.multiply(flat, q, dst=ws.idx, dtype=cv2.CV_16U)
    else:
        idx = cv2.addWeighted(flat, q, noise, q, 0.0, dst=ws.idx, dtype=cv2.CV_16U)
    out = np.take(tone, idx, out=ws.out, mode="clip").reshape(h, w, 3)
    return jpeg_roundtrip(out, int(sensor.jpeg_quality))


# ---------------------------------------------------------------- real H.264 on a clip
def encode_h264_roundtrip(frames: Sequence[np.ndarray], crf: int, fps: float = 30.0, gop: int = 30,
                          preset: str = "veryfast") -> list[np.ndarray]:
    """A clip of uint8 BGR frames (same even H, W) through libx264 (yuv420p, ``crf``) and back.

    Real inter-frame coding: I/P/B frames, a keyframe every ``gop`` frames, motion-compensated
    drift. Bit-exact run to run and machine to machine: one encoder thread, bit-exact swscale
    (BT.601 limited range both ways). Uses the ffmpeg bundled with imageio-ffmpeg; the clip goes
    through a temporary .mkv file. Returns as many frames as it was given.
    """
    import imageio_ffmpeg

    if len(frames) == 0:
        return []
    h, w = frames[0].shape[:2]
    if h % 2 or w % 2:
        raise ValueError(f"4:2:0 needs even frame sizes, got {w}x{h}")
    for f in frames:
        if f.shape != (h, w, 3) or f.dtype != np.uint8:
            raise ValueError(f"expected ({h}, {w}, 3) uint8 frames, got {f.shape} {f.dtype}")
    exe = imageio_ffmpeg.get_ffmpeg_exe()
    sws = ["-sws_flags", "bicubic+accurate_rnd+bitexact+full_chroma_int"]
    with tempfile.TemporaryDirectory() as tmp:
        path = str(Path(tmp) / "clip.mkv")
        enc = [exe, "-v", "error", "-y", "-f", "rawvideo", "-pix_fmt", "bgr24", "-s", f"{w}x{h}",
               "-r", f"{fps}", "-i", "-", *sws, "-c:v", "libx264", "-preset", preset, "-crf", str(int(crf)),
               "-g", str(int(gop)), "-pix_fmt", "yuv420p", "-threads", "1",
               "-x264-params", "threads=1:lookahead-threads=1", "-fflags", "+bitexact",
               "-flags:v", "+bitexact", path]
        subprocess.run(enc, input=b"".join(np.ascontiguousarray(f).tobytes() for f in frames),
                       check=True, capture_output=True)
        dec = [exe, "-v", "error", "-threads", "1", "-i", path, *sws, "-f", "rawvideo",
               "-pix_fmt", "bgr24", "-fps_mode", "passthrough", "-"]
        raw = subprocess.run(dec, check=True, capture_output=True).stdout
    n = len(raw) // (h * w * 3)
    if n != len(frames):
        raise RuntimeError(f"H.264 round trip returned {n} frames for {len(frames)}")
    clip = np.frombuffer(raw, np.uint8).reshape(n, h, w, 3)
    return [clip[i].copy() for i in range(n)]
