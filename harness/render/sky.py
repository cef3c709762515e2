"""The sky of the realistic look: a dome with a horizon-to-zenith gradient, a glow around the sun
and clouds, as vertex-coloured triangles (pure numpy).

The dome is centred on the origin (the renderer keeps it centred on the camera) in the world
frame W (Z up); its faces face inwards, towards the centre. Elevation rings run from
``-BELOW_DEG`` (so no gap shows under the horizon on a crest) to the zenith, closer together near
the horizon, where the colour changes fastest.

Colour of a direction ``d`` at elevation ``e`` (linear light, gamma 2.2 as in
:mod:`harness.render.shading`; sRGB 0..1 out):

- gradient: ``H + (Z - H) g(e)``, ``g = (1 - exp(-sin e / 0.2)) / (1 - exp(-5))`` (0 at and below the
  horizon, 1 at the zenith), H and Z the look's horizon and zenith colours;
- sun glow: added warm white ``0.45 b(70 deg)^2 + 0.6 b(12 deg)^4``, ``b(r) = max(0, (cos a - cos r)
  / (1 - cos r))`` at the angle ``a`` from the sun (nothing beyond 70 deg), dimmed by cloud;
- clouds: a seeded tileable fractal value noise on the cloud layer (the direction projected onto
  a plane above the camera, ``d_xy / (sin e + 0.1)``), thresholded by ``cloud_cover`` (0: none at
  all, 1: overcast everywhere), grey-white (darker as the cover thickens), thinning towards the
  horizon.

With ``cloud_cover = 0`` the horizon ring (and everything below it) is exactly the look's
horizon colour and the zenith exactly its zenith colour, wherever the sun is more than 70 deg away.
"""

from __future__ import annotations

import math

import numpy as np

from harness.render.look import SkyLook

SKY_RADIUS_M = 5800.0
"""Default dome radius (m): beyond the hills (:data:`harness.render.roadside.HILL_MAX_DISTANCE_M`),
inside the renderer's far plane (6000 m)."""
BELOW_DEG = 10.0
GAMMA = 2.2
GLOW_WIDE_DEG, GLOW_NARROW_DEG = 70.0, 12.0
NOISE_GRID = 64
"""Cells per period of the cloud noise (its coarsest octave has 4 cells per period)."""
CLOUD_PERIOD = 3.0
"""Period of the cloud noise on the cloud layer (units of the layer's height)."""


def elevations(n_elevation: int) -> np.ndarray:
    """Ring elevations (rad): ``-BELOW_DEG``, ``-BELOW_DEG / 3``, 0, then ``n_elevation`` steps up to
    90 deg, spaced as ``(k / n)^1.6`` (closer near the horizon)."""
    up = 0.5 * math.pi * (np.arange(1, n_elevation + 1) / n_elevation) ** 1.6
    return np.r_[math.radians(-BELOW_DEG), math.radians(-BELOW_DEG / 3), 0.0, up]


def tileable_noise(seed: int, u: np.ndarray, v: np.ndarray, octaves: int = 5) -> np.ndarray:
    """Fractal value noise in [0, 1] at ``(u, v)``, periodic with period 1 in both (seeded).

    Octave k has ``4 * 2^k`` cells per period, smoothstep-interpolated random values at the cell
    corners (wrapped), weight ``0.5^k``."""
    rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, 0xC10D])
    total, weight = np.zeros(np.shape(u)), 0.0
    for k in range(octaves):
        cells = 4 * 2 ** k
        grid = rng.uniform(0, 1, (cells, cells))
        x, y = np.mod(u, 1.0) * cells, np.mod(v, 1.0) * cells
        i, j = np.floor(x).astype(int), np.floor(y).astype(int)
        fx, fy = x - i, y - j
        fx, fy = fx * fx * (3 - 2 * fx), fy * fy * (3 - 2 * fy)
        i0, j0, i1, j1 = i % cells, j % cells, (i + 1) % cells, (j + 1) % cells
        top = grid[i0, j0] * (1 - fx) + grid[i1, j0] * fx
        bottom = grid[i0, j1] * (1 - fx) + grid[i1, j1] * fx
        total += 0.5 ** k * (top * (1 - fy) + bottom * fy)
        weight += 0.5 ** k
    return total / weight


def _smoothstep(a: float, b: float, x: np.ndarray) -> np.ndarray:
    t = np.clip((x - a) / (b - a), 0.0, 1.0)
    return t * t * (3 - 2 * t)


def sky_colours(look: SkyLook, sun_w: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """(N, 3) sRGB 0..1 sky colours of unit W ``directions`` (N, 3) for sunlight travelling along ``sun_w``."""
    d = np.asarray(directions, dtype=float)
    to_sun = -np.asarray(sun_w, dtype=float)
    to_sun = to_sun / np.linalg.norm(to_sun)
    sin_e = np.clip(d[:, 2], 0.0, 1.0)
    hor = (np.asarray(look.horizon_srgb, float) / 255.0) ** GAMMA
    zen = (np.asarray(look.zenith_srgb, float) / 255.0) ** GAMMA
    g = (1 - np.exp(-sin_e / 0.2)) / (1 - math.exp(-5.0))
    lin = hor + g[:, None] * (zen - hor)

    cover = float(np.clip(look.cloud_cover, 0.0, 1.0))
    cos_a = np.clip(d @ to_sun, -1.0, 1.0)

    def bump(radius_deg: float) -> np.ndarray:
        c = math.cos(math.radians(radius_deg))
        return np.clip((cos_a - c) / (1 - c), 0.0, None)

    glow = (0.45 * bump(GLOW_WIDE_DEG) ** 2 + 0.6 * bump(GLOW_NARROW_DEG) ** 4) * (1 - 0.85 * cover)
    lin = lin + glow[:, None] * np.array([1.0, 0.93, 0.8])

    if cover > 0:
        scale = 1.0 / (sin_e + 0.1)
        u, v = d[:, 0] * scale / CLOUD_PERIOD, d[:, 1] * scale / CLOUD_PERIOD
        n = tileable_noise(look.cloud_seed, u, v)
        threshold = 1.15 - 1.3 * cover          # 1.15: above any noise (clear); -0.15: below all (overcast)
        density = _smoothstep(threshold - 0.08, threshold + 0.08, n)
        fade = _smoothstep(0.0, 0.25, sin_e)    # clouds thin into the horizon haze (but not an overcast)
        weight = density * (fade + (1 - fade) * cover)
        grey = 0.92 - 0.42 * cover ** 1.5 - 0.25 * cover * (n - 0.5)   # thicker: darker undersides
        cloud = grey[:, None] * np.array([1.0, 1.0, 1.02]) + 0.5 * glow[:, None]
        lin = lin * (1 - weight[:, None]) + cloud * weight[:, None]
    return np.clip(lin, 0.0, 1.0) ** (1.0 / GAMMA)


def sky_dome(look: SkyLook, sun_w: np.ndarray, radius_m: float = SKY_RADIUS_M, n_azimuth: int = 128,
             n_elevation: int = 30) -> tuple[np.ndarray, np.ndarray]:
    """Inward-facing dome: ``(triangles (F, 3, 3) W m, vertex_colours (F, 3, 3) sRGB 0..1)``,
    ``n_azimuth`` sectors by the rings of :func:`elevations` and a cap at the zenith."""
    el = elevations(n_elevation)[:-1]                       # the last ring is the zenith point itself
    az = 2 * np.pi * np.arange(n_azimuth) / n_azimuth
    ce, se = np.cos(el)[:, None], np.sin(el)[:, None]
    ring = np.stack([ce * np.cos(az), ce * np.sin(az), np.broadcast_to(se, (len(el), n_azimuth))], -1)
    dirs = np.concatenate([ring.reshape(-1, 3), [[0.0, 0.0, 1.0]]])
    colours = sky_colours(look, sun_w, dirs)
    idx = np.arange(len(el) * n_azimuth).reshape(len(el), n_azimuth)
    nxt = np.roll(idx, -1, axis=1)
    lo, up, lo_n, up_n = idx[:-1], idx[1:], nxt[:-1], nxt[1:]
    bands = np.concatenate([np.stack([lo, up, up_n], -1).reshape(-1, 3), np.stack([lo, up_n, lo_n], -1).reshape(-1, 3)])
    zenith = len(dirs) - 1
    cap = np.stack([idx[-1], np.full(n_azimuth, zenith), nxt[-1]], -1)
    faces = np.concatenate([bands, cap])
    return radius_m * dirs[faces], colours[faces]
