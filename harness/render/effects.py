"""Light, weather and lens effects of a scenario's ``conditions:`` block (image space, seeded).

Scene-side (:func:`scene_lighting`): time of day, sky and emissive tail lights. Image-side
(:func:`apply`, in linear light, on the colour pass, depth buffer (m) and id mask): headlights,
bloom, glare, wet road, fog/rain extinction, rain streaks, motion blur, rolling shutter, JPEG.
Ground truth is untouched. Each effect's model: docs/weather.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from harness.render.sensor import apply_sensor
from harness.render.shading import AMBIENT, SKY_RGB
from harness.world.scenario import Conditions, Scenario
from harness.world.state import VehicleState, WorldState
from monorarp.core.camera import CameraModel

GAMMA = 2.2
KOSCHMIEDER = 3.912           # -ln(0.02): contrast falls to 2 % at the visibility distance
RAIN_VISIBILITY_M = 1500.0    # extra extinction of heavy rain (rain = 1)
STREAKS = 500                 # streaks per frame at rain = 1
LAMP_BELOW_CAMERA_M = 0.65    # ego headlamps: below the camera, ...
LAMP_AHEAD_M = 1.5            # ... ahead of it
LAMP_HALF_SPREAD = (math.radians(22.0), math.radians(5.0))   # beam 1/e half-widths: horizontal, vertical
LAMP_AIM_RAD = math.radians(-1.2)                            # beam axis below horizontal
LAMP_CUTOFF_RAD = math.radians(0.3)                          # low-beam cut-off above the axis
LAMP_I0 = 600.0               # on-axis intensity: linear ambient units x m^2
BLUR_SAMPLES = 5
FOG_RGB = (0.80, 0.82, 0.85)  # sRGB albedo of fog lit by a full day sky

_TO_LIN = ((np.arange(256) / 255.0) ** GAMMA).astype(np.float32)


@dataclass(frozen=True)
class Lighting:
    """Scene lighting of a time of day (vertex-colour side)."""

    light_w: tuple[float, float, float]   # direction the sunlight travels, world frame W
    intensity: float                      # directional intensity (shading.shade units)
    ambient: float                        # ambient level (linear)
    tint: tuple[float, float, float]      # linear RGB multiplier of all reflected light
    sky_srgb: tuple[float, float, float]  # background colour, sRGB 0..1
    night_lamps: bool                     # emissive tail lights, ego headlights, bloom
    airlight: float                       # brightness of fog/haze relative to day


def _sun(elevation_deg: float, azimuth_deg: float) -> tuple[float, float, float]:
    """Direction sunlight travels in W for a sun at that elevation, azimuth from +X towards +Y (left)."""
    e, a = math.radians(elevation_deg), math.radians(azimuth_deg)
    return (-math.cos(e) * math.cos(a), -math.cos(e) * math.sin(a), -math.sin(e))


def scene_lighting(scenario: Scenario) -> Lighting:
    """The :class:`Lighting` of ``scenario`` (``render`` light for ``day``; rain dims the sun)."""
    c, r = scenario.conditions or Conditions(), scenario.render
    if c.time_of_day == "day":
        lit = Lighting(tuple(r.light_direction), r.light_intensity, AMBIENT, (1.0, 1.0, 1.0), SKY_RGB, False, 1.0)
    elif c.time_of_day == "low_sun":     # 6 deg above the horizon, ahead and a little to the left
        lit = Lighting(_sun(6.0, 15.0), 2.5, 0.30, (1.0, 0.80, 0.58), (0.93, 0.78, 0.60), False, 0.75)
    elif c.time_of_day == "dusk":        # sun below the horizon: sky light only
        lit = Lighting(_sun(-4.0, 15.0), 0.0, 0.10, (0.85, 0.85, 1.0), (0.36, 0.33, 0.45), True, 0.20)
    else:                                # night, no street lights
        lit = Lighting(_sun(-30.0, 15.0), 0.0, 0.015, (0.75, 0.82, 1.0), (0.03, 0.035, 0.06), True, 0.03)
    if c.rain > 0:                       # overcast: the sun is dimmed, the sky greyed
        sky = np.asarray(lit.sky_srgb)
        grey = sky.mean() * 0.85
        lit = Lighting(lit.light_w, lit.intensity * (1 - 0.7 * c.rain), lit.ambient * (1 - 0.25 * c.rain),
                       lit.tint, tuple(float(v) for v in sky + c.rain * (grey - sky)), lit.night_lamps,
                       lit.airlight * (1 - 0.3 * c.rain))
    return lit


def is_neutral(c: Conditions | None) -> bool:
    """True when ``c`` changes nothing (absent, or a clear dry day with no lens effect)."""
    return c is None or (c.time_of_day == "day" and c.fog_visibility_m is None and c.rain == 0
                         and c.exposure_s == 0 and c.readout_s == 0 and c.jpeg_quality is None)


TAIL_LIGHT_EMISSIVE = (1.0, 0.13, 0.08)   # sRGB 0..1 of a lit tail lamp


def shade_faces(albedo_srgb: np.ndarray, normals: np.ndarray, light_dir: np.ndarray, lighting: Lighting
                ) -> np.ndarray:
    """(F, 3) face colours (sRGB 0..1): Lambert + ambient under ``lighting``, tinted; lit tail lamps."""
    from harness.render.meshes import TAIL_LIGHT
    from harness.render.shading import shade

    lin = shade(albedo_srgb, normals, light_dir, lighting.intensity, lighting.ambient) ** GAMMA
    out = np.clip(lin * np.asarray(lighting.tint), 0.0, 1.0) ** (1 / GAMMA)
    if lighting.night_lamps:
        lamp = np.all(np.asarray(albedo_srgb) == np.asarray(TAIL_LIGHT, dtype=float), axis=1)
        out[lamp] = TAIL_LIGHT_EMISSIVE
    return out


# ---------------------------------------------------------------- conversions
def _chan3(field: np.ndarray) -> np.ndarray:
    """(H, W) float32 -> (H, W, 3) copies (numpy broadcasts over a last axis of 3 slowly)."""
    return cv2.merge([field, field, field])


def to_linear(img: np.ndarray) -> np.ndarray:
    """uint8 sRGB-ish (gamma 2.2) -> float32 linear 0..1."""
    return _TO_LIN[img]


def to_srgb8(lin: np.ndarray) -> np.ndarray:
    """float32 linear -> uint8 (gamma 2.2, rounded)."""
    x = cv2.pow(np.clip(lin, np.float32(0.0), np.float32(1.0)), 1 / GAMMA)
    return (x * np.float32(255.0) + np.float32(0.5)).astype(np.uint8)


def linear_depth(depth01: np.ndarray, znear: float, zfar: float) -> np.ndarray:
    """OpenGL window depth d (0..1) -> camera z = n f / (f - d (f - n)) (m); 0 where nothing was drawn (d = 1)."""
    d = depth01.astype(np.float32, copy=False)
    z = np.float32(znear * zfar) / (np.float32(zfar) - d * np.float32(zfar - znear))
    z[d >= 1.0] = 0.0
    return z


def ray_length_factor(camera: CameraModel) -> np.ndarray:
    """(H, W) range / z of each pixel's ray (OpenCV pixel centres)."""
    u = (np.arange(camera.width, dtype=np.float32) - camera.cx) / camera.fx
    v = (np.arange(camera.height, dtype=np.float32) - camera.cy) / camera.fy
    return np.sqrt(1.0 + u[None, :] ** 2 + v[:, None] ** 2).astype(np.float32)


def transmittance(range_m: np.ndarray, visibility_m: float) -> np.ndarray:
    """Koschmieder: ``exp(-3.912 d / V)``; 0 for an infinite range (``range_m`` <= 0 marks sky)."""
    t = np.exp(np.float32(-KOSCHMIEDER / visibility_m) * range_m)
    return np.where(range_m > 0, t, np.float32(0.0)).astype(np.float32)


def extinction_visibility(c: Conditions) -> float | None:
    """Combined visibility (m) of fog and rain (extinction coefficients add), None if clear."""
    beta = 0.0
    if c.fog_visibility_m is not None:
        beta += KOSCHMIEDER / c.fog_visibility_m
    if c.rain > 0:
        beta += KOSCHMIEDER * c.rain / RAIN_VISIBILITY_M
    return KOSCHMIEDER / beta if beta > 0 else None


# ---------------------------------------------------------------- effect pieces
def _points_cam(z: np.ndarray, camera: CameraModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    u = (np.arange(camera.width, dtype=np.float32) - camera.cx) / camera.fx
    v = (np.arange(camera.height, dtype=np.float32) - camera.cy) / camera.fy
    return u[None, :] * z, v[:, None] * z, z


def headlight_gain(z: np.ndarray, id_mask: np.ndarray, camera: CameraModel, ambient: float) -> np.ndarray:
    """(H, W) factor ``1 + E / ambient`` of the ego's low beams, evaluated on every second pixel.

    ``E = LAMP_I0 * beam * cos(i) / r^2`` (linear ambient units): r the distance (m) from the
    lamp (``LAMP_BELOW_CAMERA_M`` below, ``LAMP_AHEAD_M`` ahead of the camera) to the surface;
    beam ``exp(-(h / tan 22deg)^2 - (e / tan 5deg)^2)`` with h, e the horizontal and vertical
    tangents of the ray about the beam axis (aimed 1.2 deg down), x0.05 above the low-beam
    cut-off; incidence: road faces up, vehicles (id mask) face the ego.
    """
    zs, ids = z[::2, ::2], id_mask[::2, ::2]
    u = ((np.arange(0, camera.width, 2, dtype=np.float32) - camera.cx) / camera.fx)[None, :]
    v = ((np.arange(0, camera.height, 2, dtype=np.float32) - camera.cy) / camera.fy)[:, None]
    R = camera.R_cam_from_ego                      # ego (x right, y fwd, z up) -> cam (OpenCV)
    lamp = R @ np.array([0.0, LAMP_AHEAD_M, -LAMP_BELOW_CAMERA_M])
    right, fwd, up = R[:, 0].astype(np.float32), R[:, 1].astype(np.float32), R[:, 2].astype(np.float32)
    dx, dy, dz = u * zs - np.float32(lamp[0]), v * zs - np.float32(lamp[1]), zs - np.float32(lamp[2])
    along = dx * fwd[0] + dy * fwd[1] + dz * fwd[2]
    side = dx * right[0] + dy * right[1] + dz * right[2]
    rise = dx * up[0] + dy * up[1] + dz * up[2]
    r2 = np.maximum(along * along + side * side + rise * rise, np.float32(1.0))
    inv_al = np.float32(1.0) / np.maximum(along, np.float32(1e-3))
    th = side * inv_al
    te = rise * inv_al - np.float32(math.tan(LAMP_AIM_RAD))
    beam = np.exp(-(th * np.float32(1 / math.tan(LAMP_HALF_SPREAD[0]))) ** 2
                  - (te * np.float32(1 / math.tan(LAMP_HALF_SPREAD[1]))) ** 2)
    beam[te > np.float32(math.tan(LAMP_CUTOFF_RAD) - math.tan(LAMP_AIM_RAD))] *= np.float32(0.05)
    cos_i = np.where(ids >= 0, along, -rise) / np.sqrt(r2)
    e = np.float32(LAMP_I0 / ambient) * beam * np.clip(cos_i, 0.0, 1.0) / r2
    e[(zs <= 0) | (along <= 0)] = 0.0
    gain = cv2.resize(e, (camera.width, camera.height), interpolation=cv2.INTER_LINEAR)
    return gain + np.float32(1.0)


BLOOM_BGR = (0.05, 0.10, 1.0)


def tail_light_bloom(lin: np.ndarray, width: int) -> np.ndarray | None:
    """(H, W) glow strength (times :data:`BLOOM_BGR`, linear) around saturated red emitters; None if none."""
    red = (lin[..., 2] > 0.6) & (lin[..., 1] < 0.2)      # BGR order: index 2 is red
    if not red.any():
        return None
    h, w = red.shape
    m = cv2.resize(red.astype(np.float32), (w // 4, h // 4), interpolation=cv2.INTER_AREA)   # blur at 1/4 size
    sigma = max(1.0, width / 320.0) / 4
    glow = cv2.GaussianBlur(m, (0, 0), sigma * 2.5) * 2.0 + cv2.GaussianBlur(m, (0, 0), sigma * 8) * 1.4
    return cv2.resize(glow, (w, h), interpolation=cv2.INTER_LINEAR)


def sun_glare(camera: CameraModel, ego: VehicleState, light_w, tint) -> np.ndarray | None:
    """(H, W) veiling glare (times the tint, linear) of a sun in (or near) view, None if behind the camera."""
    lw = np.asarray(light_w, dtype=float)
    to_sun_w = -lw / np.linalg.norm(lw)
    c, s = math.cos(ego.heading), math.sin(ego.heading)
    # W (X fwd-of-road, Y left) -> ego (x right, y fwd): rotate by the heading (road y is -Y)
    fwd = np.array([c, -s, 0.0])
    right = np.array([-s, -c, 0.0])
    d_ego = np.array([to_sun_w @ right, to_sun_w @ fwd, to_sun_w[2]])
    d = camera.R_cam_from_ego @ d_ego
    if d[2] <= 0.05:
        return None
    us, vs = camera.cx + camera.fx * d[0] / d[2], camera.cy + camera.fy * d[1] / d[2]
    u = np.arange(camera.width, dtype=np.float32) - np.float32(us)
    v = np.arange(camera.height, dtype=np.float32) - np.float32(vs)
    r2 = (u[None, :] ** 2 + v[:, None] ** 2) / np.float32(camera.width ** 2)
    g = 1.5 * np.exp(-r2 / 0.0008) + 0.35 * np.exp(-r2 / 0.02) + 0.08 * np.exp(-r2 / 0.25)
    return g.astype(np.float32)


def wet_road(z: np.ndarray, id_mask: np.ndarray, rng_len: np.ndarray, camera: CameraModel, rain: float
             ) -> tuple[np.ndarray, np.ndarray]:
    """(factor, sheen): road pixels (non-vehicle, with depth) darkened by ``1 - 0.45 rain`` and given a
    Schlick-Fresnel sky reflection ``0.3 rain (1 - cos i)^5`` (times the sky colour), cos i = camera height / range."""
    road = (id_mask < 0) & (z > 0)
    x = np.float32(1.0) - np.clip(np.float32(camera.height_m) / np.maximum(rng_len, np.float32(1e-3)), 0.0, 1.0)
    x2 = x * x
    k = road * np.float32(-0.45 * rain) + np.float32(1.0)
    sheen = road * (np.float32(0.3 * rain) * (x2 * x2 * x))
    return k.astype(np.float32), sheen.astype(np.float32)


def rain_streaks(h: int, w: int, rain: float, seed: int, frame: int) -> np.ndarray | None:
    """(H, W) opacity (0..0.35) of ``rain * STREAKS`` (per 640x360) seeded slanted anti-aliased streaks."""
    n = int(round(rain * STREAKS * w * h / (640 * 360)))
    if n == 0:
        return None
    rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, int(frame) & 0xFFFFFFFF, 0x7A1])
    p0 = rng.uniform([0, -0.1 * h], [w, h], size=(n, 2))
    length = rng.uniform(0.03, 0.12, n) * h
    ang = math.radians(8.0) + rng.normal(0, math.radians(2.0), n)
    p1 = p0 + np.stack([np.sin(ang), np.cos(ang)], axis=1) * length[:, None]
    layer = np.zeros((h, w), np.uint8)
    segs = np.stack([p0, p1], axis=1).round().astype(np.int32)
    cv2.polylines(layer, list(segs), False, 255, 1, cv2.LINE_AA)
    return layer.astype(np.float32) * np.float32(0.35 / 255)


def flow_per_second(z: np.ndarray, id_mask: np.ndarray, world: WorldState, camera: CameraModel
                    ) -> tuple[np.ndarray, np.ndarray]:
    """(H, W) image flow (px/s) along u and v of the scene relative to the camera.

    Forward motion only: a point at depth z closing at speed w (m/s) moves away from the
    focus of expansion as ``dp/dt = (p - foe) * w / z``. Static world: w = ego speed;
    a vehicle pixel: ego speed minus the vehicle's speed along the ego's heading; sky: 0.
    """
    ego = world.ego
    fwd = np.array([math.cos(ego.heading), math.sin(ego.heading)])
    n = int(max([v.id for v in world.vehicles], default=-1)) + 2
    closing = np.full(n, ego.speed, dtype=np.float32)
    for v in world.vehicles:
        closing[v.id + 1] = ego.speed - float(np.dot([v.vx, v.vy], fwd))
    w = closing[np.clip(id_mask + 1, 0, n - 1)]
    fwd_cam = camera.R_cam_from_ego @ np.array([0.0, 1.0, 0.0])
    fu, fv = camera.cx + camera.fx * fwd_cam[0] / fwd_cam[2], camera.cy + camera.fy * fwd_cam[1] / fwd_cam[2]
    k = np.where(z > 0, w / np.maximum(z, 1e-3), 0.0).astype(np.float32)
    u = np.arange(camera.width, dtype=np.float32) - np.float32(fu)
    v = np.arange(camera.height, dtype=np.float32) - np.float32(fv)
    return u[None, :] * k, v[:, None] * k


def lens_motion(lin: np.ndarray, flow: tuple[np.ndarray, np.ndarray], exposure_s: float, readout_s: float
                ) -> np.ndarray:
    """Motion blur over the exposure and rolling-shutter shift, by remapping along ``flow`` (px/s)."""
    h, w = lin.shape[:2]
    fu, fv = flow
    gu = np.arange(w, dtype=np.float32)[None, :]
    gv = np.arange(h, dtype=np.float32)[:, None]
    t_row = (np.float32(readout_s) * ((gv + 0.5) / h - 0.5)).astype(np.float32)   # (H, 1) s from frame time
    offsets = [0.0] if exposure_s == 0 else list(np.linspace(-0.5, 0.5, BLUR_SAMPLES) * exposure_s)
    acc = np.zeros_like(lin)
    for dt in offsets:
        t = t_row + np.float32(dt)
        # the scene point seen at p at time t was at p - flow * t at the frame time
        mx = (gu - fu * t).astype(np.float32)
        my = (gv - fv * t).astype(np.float32)
        acc += cv2.remap(lin, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    return acc / np.float32(len(offsets))


def jpeg(image: np.ndarray, quality: int) -> np.ndarray:
    ok, buf = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    return cv2.imdecode(buf, cv2.IMREAD_COLOR)


# ---------------------------------------------------------------- orchestration
class _Affine:
    """The per-pixel affine map ``out = lin * m + sum_j field_j * colour_j`` of the light/weather steps,
    composed on (H, W) fields and applied to the (H, W, 3) image once (two full-colour passes in all)."""

    def __init__(self, h: int, w: int) -> None:
        self.m: np.ndarray | None = None
        self.add = [None, None, None]     # B, G, R

    def mul(self, m: np.ndarray) -> None:
        self.m = m if self.m is None else self.m * m
        self.add = [None if a is None else a * m for a in self.add]

    def plus(self, field: np.ndarray, bgr) -> None:
        for i, c in enumerate(bgr):
            term = field * np.float32(c)
            self.add[i] = term if self.add[i] is None else self.add[i] + term

    def apply(self, lin: np.ndarray) -> np.ndarray:
        if self.m is not None:
            lin = lin * _chan3(self.m.astype(np.float32))
        if any(a is not None for a in self.add):
            zero = np.zeros(lin.shape[:2], np.float32)
            lin = lin + cv2.merge([zero if a is None else a.astype(np.float32) for a in self.add])
        return lin


def apply(bgr: np.ndarray, z: np.ndarray | None, id_mask: np.ndarray, world: WorldState, scenario: Scenario,
          lighting: Lighting, ray_factor: np.ndarray) -> np.ndarray:
    """All image-space effects of ``scenario.conditions`` on a colour pass (BGR uint8), then the sensor."""
    c, cam, r = scenario.conditions, scenario.camera.model(), scenario.render
    h, w = bgr.shape[:2]
    lin = to_linear(bgr)
    sky_lin = to_linear(np.round(np.asarray(lighting.sky_srgb[::-1]) * 255).astype(np.uint8)).astype(float)
    rng_len = z * ray_factor if z is not None else None
    acc = _Affine(h, w)
    if lighting.night_lamps and z is not None:
        if c.headlights:
            acc.mul(headlight_gain(z, id_mask, cam, lighting.ambient))
        glow = tail_light_bloom(lin, cam.width)
        if glow is not None:
            acc.plus(glow, BLOOM_BGR)
    if c.time_of_day == "low_sun":
        glare = sun_glare(cam, world.ego, lighting.light_w, lighting.tint)
        if glare is not None:
            acc.plus(glare, lighting.tint[::-1])
    if c.rain > 0 and z is not None:
        k, sheen = wet_road(z, id_mask, rng_len, cam, c.rain)
        acc.mul(k)
        acc.plus(sheen, sky_lin)
    vis = extinction_visibility(c)
    if vis is not None and z is not None:
        fog_bgr = (np.asarray(FOG_RGB[::-1]) ** GAMMA) * lighting.airlight * np.asarray(lighting.tint[::-1])
        t = transmittance(rng_len, vis)
        acc.mul(t)
        acc.plus(np.float32(1.0) - t, fog_bgr)
    if c.rain > 0:
        a = rain_streaks(h, w, c.rain, scenario.seed, world.frame)
        if a is not None:
            streak = np.minimum(np.maximum(sky_lin, 0.08 * lighting.airlight + 0.02) * 1.3, 1.0)
            acc.mul(np.float32(1.0) - a)
            acc.plus(a, streak)
    lin = acc.apply(lin)
    if (c.exposure_s > 0 or c.readout_s > 0) and z is not None:
        lin = lens_motion(lin, flow_per_second(z, id_mask, world, cam), c.exposure_s, c.readout_s)
    out = apply_sensor(to_srgb8(lin), r.noise_std, r.blur_px, scenario.seed, world.frame)
    if c.jpeg_quality is not None:
        out = jpeg(out, c.jpeg_quality)
    return out
