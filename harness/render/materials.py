"""Per-face material model of the realistic look: hemisphere sky light, sun, and a view-independent
stand-in for reflections, baked into face colours (drawn with pyrender's FLAT shader, as
:mod:`harness.render.shading`).

For a face of unit normal ``n`` (any frame with Z up: W, or a vehicle's model frame), linear albedo
``a`` (sRGB ``/ 255`` to the power 2.2) and ``l`` the unit vector towards the sun (``-light_dir``)::

    sky     = A * tint                                     tint: the sky's hue at luminance 1 (softened)
    ground  = g * (A * tint + I / pi * max(0, l_z))         g: the ground's linear albedo
    hemi    = w * sky + (1 - w) * ground,  w = (1 + n_z) / 2
    direct  = I / pi * max(0, n . l) * (1 - shadow_strength * in_shadow)
    env     = (1 - q) * lerp(horizon, zenith, max(0, n_z)) + q * ground,  q = (1 - n_z) / 2
    linear  = a * (hemi + direct) + R(material, n_z, gloss) * env + E(material) * a

with ``A = sun.ambient``, ``I = sun.intensity`` (the units of :func:`harness.render.shading.shade`),
``zenith``/``horizon`` the sky's linear colours as the background shows them. ``R`` is the share of
the environment a face reflects: glossy paint ``gloss * (0.05 + 0.20 max(0, n_z))``, glass
``0.06 + 0.22 max(0, n_z)`` (a dark interior with a sky sheen, roofs and bonnets brighter than
sides), rims and lamp covers less, matte surfaces, tyres and dirt none. ``E`` makes lamps look lit
from inside (retro-reflection in daylight). :attr:`Material.SHADOW` (the dark ground under a vehicle)
takes the sky term only: no sun, no ground bounce, no reflection. Output: sRGB 0..1 (gamma 1/2.2,
clipped), as :func:`harness.render.shading.shade`.

:attr:`Material.METALLIC` is metallic paint (aluminium flakes under the clear coat): its diffuse part is
darker (``a * METALLIC_DIFFUSE``), its reflection share stronger (``gloss * (0.12 + 0.40 max(0, n_z))``) and
tinted by the paint (the flakes reflect in the pigment's hue: ``env * lerp(1, hue(a), METALLIC_TINT)``,
``hue`` the albedo at luminance 1), so a metallic body is darker on its sides and brighter, in its own
colour, where it faces the sky. Per face, in the same pass: no extra cost. :func:`is_metallic` picks which
vehicles have it (:data:`METALLIC_SHARE`), :func:`metallic_paint` re-tags their paint. Upward faces of matte material under a grey sky
reduce exactly to :func:`~harness.render.shading.shade` with ``ambient = A``.
"""

from __future__ import annotations

import math
from enum import IntEnum

import numpy as np

from harness.render.look import SkyLook, SunLook
from harness.world.vehicles import HEAVY_BODIES

GAMMA = 2.2
#: Linear albedo of the ground under the sky when the caller gives none (a mid asphalt, sRGB 0..255).
GROUND_SRGB = (90, 90, 88)
#: How much of the sky's hue the ambient light keeps (0: grey, 1: the sky's own colour at luminance 1).
SKY_TINT = 0.5
_LUMA = np.array([0.2126, 0.7152, 0.0722])


class Material(IntEnum):
    """What a face is made of: the tag :func:`shade_realistic` shades it by."""

    MATTE = 0     # static surfaces: road, verge, roadside objects
    PAINT = 1     # body paint (glossy: clear coat)
    GLASS = 2     # windows: dark interior behind a reflecting pane
    TYRE = 3      # rubber, matte
    RIM = 4       # wheel rims, metallic
    LIGHT = 5     # lamp clusters (red, amber, white)
    PLATE = 6     # number plates (retro-reflective)
    TRIM = 7      # black plastic, grilles, recesses, panel gaps, plate characters
    DIRT = 8      # road grime on the lower body, matte
    SHADOW = 9    # the ground under a vehicle, lit by the part of the sky it sees only
    METALLIC = 10  # metallic body paint: darker diffuse, stronger reflection tinted by the paint


#: Per material: reflection share at a vertical face, extra share at an upward face, emission share.
#: Paint's reflection shares are multiplied by ``gloss``.
_REFLECT = np.zeros((len(Material), 3))
_REFLECT[Material.PAINT] = (0.05, 0.20, 0.0)
_REFLECT[Material.GLASS] = (0.06, 0.22, 0.0)
_REFLECT[Material.RIM] = (0.12, 0.10, 0.0)
_REFLECT[Material.LIGHT] = (0.03, 0.06, 0.45)
_REFLECT[Material.PLATE] = (0.02, 0.02, 0.12)
_REFLECT[Material.TRIM] = (0.015, 0.03, 0.0)
_REFLECT[Material.METALLIC] = (0.12, 0.40, 0.0)
#: Metallic paint: the share of the albedo its diffuse part keeps, and how far its reflection takes the paint's hue.
METALLIC_DIFFUSE, METALLIC_TINT = 0.75, 0.6
#: Share of light vehicles (cars, vans, pickups) and of heavy ones (lorries, buses: their cabs) with metallic paint
#: (assumed: about half of the European car fleet's paint is metallic or pearl, the paint makers' colour reports;
#: fleet lorries and buses mostly solid colours).
METALLIC_SHARE = {"light": 0.5, "heavy": 0.15}


def srgb_to_linear(srgb255) -> np.ndarray:
    """sRGB 0..255 -> linear 0..1 (gamma 2.2)."""
    return (np.asarray(srgb255, dtype=float) / 255.0) ** GAMMA


def sky_tint(sky: SkyLook) -> np.ndarray:
    """(3,) linear RGB hue of the sky light at luminance 1, softened towards grey by :data:`SKY_TINT`."""
    mean = 0.5 * (srgb_to_linear(sky.zenith_srgb) + srgb_to_linear(sky.horizon_srgb))
    hue = mean / max(float(mean @ _LUMA), 1e-6)
    return (1.0 - SKY_TINT) + SKY_TINT * hue


def sun_light_dir(sun: SunLook) -> np.ndarray:
    """(3,) unit direction sunlight travels in the world frame W (azimuth from +X towards +Y, elevation up)."""
    e, a = math.radians(sun.elevation_deg), math.radians(sun.azimuth_deg)
    return -np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])


def shade_realistic(albedo_srgb: np.ndarray, normals: np.ndarray, material: np.ndarray, light_dir: np.ndarray,
                    sun: SunLook, sky: SkyLook, gloss: float, in_shadow: np.ndarray | None = None,
                    ground_srgb=GROUND_SRGB) -> np.ndarray:
    """(F, 3) sRGB albedo (0..255), unit normals, (F,) :class:`Material` tags -> (F, 3) sRGB colours 0..1.

    ``light_dir``: the direction sunlight travels, in the normals' frame (Z up). ``in_shadow``: (F,) bool or
    0..1 fraction of each face in the sun's shadow (None: none). ``gloss`` 0..1 scales the paint's reflection.
    ``ground_srgb``: the ground's colour (e.g. the look's asphalt), the light from below.
    """
    a = srgb_to_linear(albedo_srgb)
    n = np.asarray(normals, dtype=float)
    mat = np.asarray(material, dtype=np.int64)
    to_sun = -np.asarray(light_dir, dtype=float)
    to_sun = to_sun / np.linalg.norm(to_sun)
    amb, beam = float(sun.ambient), float(sun.intensity) / math.pi
    tint = sky_tint(sky)
    sky_light = amb * tint
    ground = srgb_to_linear(ground_srgb) * (sky_light + beam * max(0.0, float(to_sun[2])))
    nz = np.clip(n[:, 2], -1.0, 1.0)[:, None]
    w = 0.5 * (1.0 + nz)
    shadow = np.zeros(len(n)) if in_shadow is None else np.asarray(in_shadow, dtype=float).reshape(len(n))
    direct = beam * np.clip(n @ to_sun, 0.0, None) * (1.0 - float(sun.shadow_strength) * shadow)
    is_shadow = (mat == Material.SHADOW)[:, None]
    light = np.where(is_shadow, sky_light, w * sky_light + (1.0 - w) * ground + direct[:, None])
    up = np.clip(nz, 0.0, None)
    sky_env = (1.0 - up) * srgb_to_linear(sky.horizon_srgb) + up * srgb_to_linear(sky.zenith_srgb)
    q = 0.5 * (1.0 - nz)
    env = (1.0 - q) * sky_env + q * ground
    base, extra, emit = _REFLECT[mat].T
    glossy = (mat == Material.PAINT) | (mat == Material.METALLIC)
    share = (base[:, None] + extra[:, None] * up) * np.where(glossy, float(gloss), 1.0)[:, None]
    metallic = (mat == Material.METALLIC)[:, None]
    if metallic.any():
        hue = a / np.maximum(a @ _LUMA, 1e-3)[:, None]
        env = np.where(metallic, env * ((1.0 - METALLIC_TINT) + METALLIC_TINT * np.clip(hue, 0.0, 3.0)), env)
        light = np.where(metallic, METALLIC_DIFFUSE * light, light)
    out = a * light + share * env + emit[:, None] * a
    return np.clip(out, 0.0, 1.0) ** (1.0 / GAMMA)


def shade_matte(albedo_srgb: np.ndarray, normals: np.ndarray, light_dir: np.ndarray, sun: SunLook, sky: SkyLook,
                in_shadow: np.ndarray | None = None, ground_srgb=GROUND_SRGB) -> np.ndarray:
    """:func:`shade_realistic` of static surfaces (road, verge, roadside objects): every face :attr:`Material.MATTE`."""
    mat = np.full(len(np.asarray(normals)), int(Material.MATTE))
    return shade_realistic(albedo_srgb, normals, mat, light_dir, sun, sky, 0.0, in_shadow, ground_srgb)


def is_metallic(look_seed: int, vehicle_id: int, body: str | None = None) -> bool:
    """Whether a vehicle's paint is metallic (:data:`METALLIC_SHARE`; deterministic per look and id)."""
    rng = np.random.default_rng([int(look_seed) & 0xFFFFFFFF, int(vehicle_id) & 0xFFFFFFFF, 0x3E7A])
    return bool(rng.uniform() < METALLIC_SHARE["heavy" if body in HEAVY_BODIES else "light"])


def metallic_paint(material: np.ndarray, metallic: bool) -> np.ndarray:
    """``material`` (F,) with its :attr:`Material.PAINT` faces re-tagged :attr:`Material.METALLIC` when ``metallic``."""
    if not metallic:
        return material
    out = np.array(material, copy=True)
    out[out == Material.PAINT] = Material.METALLIC
    return out
