"""Procedural road-surface textures of the realistic look, and the textured meshes that carry them.

Every texture is an (H, W, 3) uint8 sRGB array, seeded by ``SurfaceLook.texture_seed`` (one random
stream per surface kind) and tileable: it repeats seamlessly along both axes. Columns run along the
texture's u (along the road), rows across its v; as pyrender uploads it (rows flipped), row 0 is
sampled at v = 1 and row H - 1 at v = 0, column 0 at u = 0. A pixel covers about 1.5 cm of road
(marking paint 4 mm x 8 mm), so the mipmaps average the grain away with distance.

- ``asphalt``: ONE LANE, u along ``Tiling.asphalt_m`` (16 m, or the multiple of the seam spacing
  nearest 16 m so the seams stay periodic), v across one lane width (lane centre at v = 0.5).
  Aggregate grain (multi-octave value noise plus sparse light stones and dark pores), wheel tracks
  at the lane centre +-0.85 m (darker for oil, lighter and smoother when polished), an oil strip
  between them, repair patches with sealed edges, tar seams across, low-frequency blotches.
- ``marking``: white paint with speckled wear showing grey asphalt through it.
- ``shoulder``: coarse, gravelly asphalt with loose stones.
- ``grass``: the verge, patchy with dry (straw) and dark spots.
- ``pavement`` (a street's only, :func:`pavement_texture`): square paving slabs with dark joints, each
  slab's tone a little different, fine grain and grime.

Colour convention: the TEXTURES CARRY THE ALBEDO. Each texture's mean is its look colour
(``asphalt_srgb``, ``shoulder_srgb``, ``grass_srgb``; the marking's mean is worn paint) and the
vertex colours carry only the shading: pyrender's FLAT shader multiplies texel (sRGB / 255) by
vertex colour, so the vertex colour of a face is its shaded mean colour divided by the mean
(:func:`vertex_rgb`). The shading (:func:`harness.render.shading.shade`, ``effects.shade_faces``) is
a power law in sRGB, ``shade(a) = a / 255 * f ** (1 / 2.2)``, so texel x vertex colour is exactly
the shaded texel for every texel the shading does not clip; vertex colours may exceed 1 (the
shader clamps the product only).

Per-lane variety: lane i's texture is shifted along the road by a multiple of the seam spacing
and mirrored along it in odd lanes (:class:`harness.render.road.Tiling`), so patches do not stand
side by side in every lane while the seams run straight across the road. A texture still repeats
every tile along a lane: a repair patch recurs every ``asphalt_m``, so ``patch_density`` sets the
expected patches per tile (``density * asphalt_m / 100``, Poisson), not an exact density per 100 m.
With 30 m seams the tile is one seam spacing, no shift is possible and only the mirroring
separates neighbouring lanes (lanes 0 and 2 run alike).
"""

from __future__ import annotations

import math
import os

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

import cv2  # noqa: E402
import numpy as np  # noqa: E402
import pyrender  # noqa: E402

from harness.render.look import StreetLook, SurfaceLook  # noqa: E402
from harness.render.road import SURFACE_COLORS, Tiling  # noqa: E402

#: Texture sizes (rows across v, columns along u).
ASPHALT_SHAPE = (256, 1024)
MARKING_SHAPE = (128, 512)
SHOULDER_SHAPE = (256, 512)
GRASS_SHAPE = (256, 1024)
ASPHALT_TILE_M = 16.0
WHEEL_TRACK_M = 0.85          # wheel-track centres from the lane centre
WHEEL_TRACK_SIGMA_M = 0.28
PAINT_SRGB = SURFACE_COLORS["marking"]
PAVEMENT_SHAPE = (256, 512)
_KINDS = {"asphalt": 1, "marking": 2, "shoulder": 3, "grass": 4, "pavement": 5}


# ---------------------------------------------------------------------------- noise
_COARSE = 4
"""Octaves with periods of at least 2 _COARSE px are drawn at 1 / _COARSE resolution and scaled up together."""


def _scale_periodic(field: np.ndarray, fy: int, fx: int) -> np.ndarray:
    """A tileable (h, w) field scaled up bicubically by integer factors (pixel centres aligned), still tileable."""
    h, w = field.shape
    if max(fy, fx) >= 32:      # coarse: scale in place with wrapped borders (no padding to crop)
        m = np.array([[1 / fx, 0, 0.5 / fx - 0.5], [0, 1 / fy, 0.5 / fy - 0.5]])
        return cv2.warpAffine(field, m, (w * fx, h * fy), flags=cv2.INTER_CUBIC | cv2.WARP_INVERSE_MAP,
                              borderMode=cv2.BORDER_WRAP)
    pad = 2                    # fine: wrap two cells round it, scale, crop
    big = cv2.resize(np.pad(field, pad, mode="wrap"), ((w + 2 * pad) * fx, (h + 2 * pad) * fy),
                     interpolation=cv2.INTER_CUBIC)
    return big[pad * fy:(pad + h) * fy, pad * fx:(pad + w) * fx]


def _octave(rng: np.random.Generator, shape: tuple[int, int], period_px: tuple[int, int]) -> np.ndarray:
    """Periodic value noise: a Gaussian lattice of ``period_px`` (rows, cols; powers of two) cells,
    bicubic between lattice points (a period of 1 px is white noise). float32, std ~ 0.5..1."""
    h, w = shape
    py, px = max(1, period_px[0]), max(1, period_px[1])
    lattice = rng.standard_normal((h // py, w // px), dtype=np.float32)
    return lattice if py == px == 1 else _scale_periodic(lattice, py, px)


def _pow2_px(length_m: float, pixel_m: float, n: int) -> int:
    """The power of two (1..n) number of pixels nearest ``length_m`` at ``pixel_m`` per pixel."""
    return int(min(n, 2 ** max(0, round(math.log2(max(length_m / pixel_m, 1.0))))))


def _fbm(rng: np.random.Generator, shape: tuple[int, int], size_m: tuple[float, float],
         periods_m: tuple[float, ...], gains: tuple[float, ...]) -> np.ndarray:
    """Multi-octave periodic value noise over a tile of ``size_m`` (across, along; m), octave
    periods in metres (rounded per axis to powers of two pixels), zero mean, unit std."""
    out = np.zeros(shape, np.float32)
    coarse = np.zeros((shape[0] // _COARSE, shape[1] // _COARSE), np.float32)
    for p, g in zip(periods_m, gains):
        period = (_pow2_px(p, size_m[0] / shape[0], shape[0]), _pow2_px(p, size_m[1] / shape[1], shape[1]))
        if min(period) >= 2 * _COARSE:    # smooth octaves: summed at 1 / _COARSE resolution, scaled up once
            coarse += np.float32(g) * _octave(rng, coarse.shape, (period[0] // _COARSE, period[1] // _COARSE))
        else:
            out += np.float32(g) * _octave(rng, shape, period)
    if coarse.any():
        out += _scale_periodic(coarse, _COARSE, _COARSE)
    out -= out.mean()
    return out / max(float(out.std()), 1e-6)


def _grid(shape: tuple[int, int], size_m: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """Pixel-centre coordinates (m) across (rows, from v = 0) and along (cols, from u = 0), (H, 1) and (1, W)."""
    h, w = shape
    return ((np.arange(h, dtype=np.float32) + 0.5) * (size_m[0] / h))[:, None], \
        ((np.arange(w, dtype=np.float32) + 0.5) * (size_m[1] / w))[None, :]


def _wrap(d: np.ndarray, period: float) -> np.ndarray:
    """Signed distance on a circle of ``period``: in [-period / 2, period / 2)."""
    return (d + period / 2) % period - period / 2


def _to_srgb8(value: np.ndarray, tint: np.ndarray, mean_srgb) -> np.ndarray:
    """(H, W) relative brightness times (H, W, 3) tint -> uint8 rows flipped (row 0 at v = 1), each
    channel scaled to mean ``mean_srgb``."""
    rgb = np.maximum(value, 0.0)[..., None] * tint
    target = np.asarray(mean_srgb, np.float32)
    for _ in range(3):      # clipping at 255 moves the mean: rescale while anything clips
        rgb *= target / np.maximum(rgb.reshape(-1, 3).mean(0), 1e-6)
        if rgb.max() <= 255.0:
            break
        np.minimum(rgb, 255.0, out=rgb)
    return np.ascontiguousarray((rgb[::-1] + 0.5).astype(np.uint8))


def _tint(rng: np.random.Generator, shape: tuple[int, int], size_m, amount: float) -> np.ndarray:
    """(H, W, 3) colour variation about 1: warm/cool per stone and per patch of ground."""
    warm = amount * (0.7 * _fbm(rng, shape, size_m, (0.02, 0.04), (1.0, 0.5))
                     + 0.5 * _fbm(rng, shape, size_m, (1.0, 2.0), (1.0, 0.6)))
    return np.stack([1 + warm, np.ones_like(warm), 1 - warm], axis=-1)


def _grain(rng: np.random.Generator, shape, size_m, stone_m: float) -> np.ndarray:
    """Aggregate grain about 0 (std ~1): value noise at the stone size plus sparse light stones and dark pores."""
    g = _fbm(rng, shape, size_m, (stone_m, 2 * stone_m, 4 * stone_m), (1.0, 0.6, 0.35))
    white = _fbm(rng, shape, size_m, (stone_m,), (1.0,))
    return g + 1.6 * (white > 2.0) - 1.3 * (white < -1.9)


def _rng(surface: SurfaceLook, kind: str) -> np.random.Generator:
    return np.random.default_rng([int(surface.texture_seed) & 0xFFFFFFFF, 0x7E47, _KINDS[kind]])


# ------------------------------------------------------------------------- tiling
def road_tiling(surface: SurfaceLook) -> Tiling:
    """Texture tile sizes for ``surface``: the asphalt tile is 16 m, or with tar seams the multiple
    of ``seam_spacing_m`` nearest 16 m (lanes then shift by whole seam spacings)."""
    s = float(surface.seam_spacing_m)
    if s <= 0:
        return Tiling(asphalt_m=ASPHALT_TILE_M, asphalt_shift_m=0.0)
    return Tiling(asphalt_m=max(1, round(ASPHALT_TILE_M / s)) * s, asphalt_shift_m=s)


# ------------------------------------------------------------------------ surfaces
def asphalt_texture(surface: SurfaceLook, lane_width_m: float, tile_m: float | None = None) -> np.ndarray:
    """One lane of asphalt: (256, 1024, 3) uint8, u along ``tile_m`` (default :func:`road_tiling`),
    v across ``lane_width_m`` with the lane centre at v = 0.5; mean ``surface.asphalt_srgb``."""
    tile = road_tiling(surface).asphalt_m if tile_m is None else float(tile_m)
    shape, size = ASPHALT_SHAPE, (float(lane_width_m), tile)
    rng = _rng(surface, "asphalt")
    y, x = _grid(shape, size)
    y = y - lane_width_m / 2                                   # from the lane centre, + right
    wear = float(surface.wheel_track_wear)
    contrast = 0.4 * float(surface.aggregate_contrast)

    grain = _grain(rng, shape, size, 0.015)
    blotch = _fbm(rng, shape, size, (0.5, 1.0, 2.0, 4.0), (0.3, 0.5, 0.8, 1.0))
    along = _fbm(rng, shape, size, (2.0, 4.0), (0.5, 1.0))       # how worn the tracks are, along the road
    band = np.exp(-0.5 * ((np.abs(y) - WHEEL_TRACK_M) / WHEEL_TRACK_SIGMA_M) ** 2) * (1 + 0.25 * along)
    oil = np.exp(-0.5 * (y / 0.22) ** 2) * (1 + 0.4 * along)
    tone = 1 + 0.035 * blotch + 0.22 * wear * band - (0.03 + 0.05 * max(-wear, 0.0)) * oil
    local = contrast * (1 - 0.5 * max(wear, 0.0) * band)       # polished tracks are smoother
    value = tone * (1 + local * grain)

    # Repair patches: rectangles (wrapped on the tile) of fresher or older asphalt, edges sealed with tar.
    jitter = 0.02 * _fbm(rng, shape, size, (0.05, 0.1), (1.0, 0.5))
    for _ in range(int(rng.poisson(float(surface.patch_density) * tile / 100.0))):
        half_u = min(rng.uniform(0.75, 3.0), 0.45 * tile)
        half_v = rng.uniform(0.3, 0.5) * lane_width_m * rng.choice([0.7, 1.0])
        cu, cv = rng.uniform(0, tile), rng.uniform(-0.25, 0.25) * lane_width_m
        du = np.abs(_wrap(x - cu, tile)) + jitter
        dv = np.abs(y - cv) + jitter
        edge = np.maximum(du - half_u, dv - half_v)          # < 0 inside, m
        inside = np.clip(0.5 - edge / (size[1] / shape[1]), 0.0, 1.0)
        fresh = rng.uniform() < 0.6
        patch_tone = rng.uniform(0.78, 0.9) if fresh else rng.uniform(1.05, 1.12)
        patch = patch_tone * (1 + 0.035 * blotch) * (1 + contrast * rng.uniform(0.5, 0.9) * grain)
        value = value * (1 - inside) + patch * inside
        seal = np.exp(-0.5 * (edge / rng.uniform(0.015, 0.03)) ** 2)
        value = value * (1 - 0.35 * seal)

    # Tar seams across the road every seam_spacing_m, meandering by a few cm.
    s = float(surface.seam_spacing_m)
    if s > 0:
        meander = 0.03 * _fbm(rng, shape, size, (0.5, 1.0), (1.0, 0.5))
        d = np.abs(_wrap(x + meander, s))
        core, bleed = rng.uniform(0.008, 0.015), rng.uniform(0.03, 0.06)
        value = value * (1 - 0.45 * np.exp(-0.5 * (d / core) ** 2) - 0.12 * np.exp(-0.5 * (d / bleed) ** 2))
    return _to_srgb8(value, _tint(rng, shape, size, 0.015), surface.asphalt_srgb)


def marking_texture(surface: SurfaceLook, tile_m: tuple[float, float] = Tiling.marking_m) -> np.ndarray:
    """White paint with wear: (128, 512, 3) uint8 over ``tile_m`` (along, across; m). A share
    ``0.85 marking_wear`` of the paint is lost in speckles and flakes, showing grey asphalt."""
    shape, size = MARKING_SHAPE, (tile_m[1], tile_m[0])
    rng = _rng(surface, "marking")
    wear = float(np.clip(surface.marking_wear, 0.0, 1.0))
    paint = np.asarray(PAINT_SRGB, np.float32) * (1 - 0.12 * wear)
    grey = np.asarray(surface.asphalt_srgb, np.float32) * 1.1
    beads = 0.05 * _fbm(rng, shape, size, (0.004, 0.008), (1.0, 0.5))
    loss = _fbm(rng, shape, size, (0.004, 0.01, 0.03, 0.08, 0.3), (0.6, 0.8, 1.0, 0.8, 0.6))
    if wear > 0:
        lost = loss > np.quantile(loss, 1 - 0.85 * wear)
        lost = cv2.GaussianBlur(np.pad(lost.astype(np.float32), 1, mode="wrap"), (3, 3), 0.6)[1:-1, 1:-1]
    else:
        lost = np.zeros(shape, np.float32)
    asphalt = 1 + 0.4 * float(surface.aggregate_contrast) * _grain(rng, shape, size, 0.008)
    rgb = ((1 - lost)[..., None] * paint * (1 + beads)[..., None]
           + lost[..., None] * grey * asphalt[..., None])
    rgb = np.clip(rgb, 0, 255)
    return np.ascontiguousarray(np.round(rgb[::-1]).astype(np.uint8))


def shoulder_texture(surface: SurfaceLook, tile_m: tuple[float, float] = Tiling.shoulder_m) -> np.ndarray:
    """Coarse, gravelly asphalt with loose stones and dirt: (256, 512, 3) uint8, mean ``surface.shoulder_srgb``."""
    shape, size = SHOULDER_SHAPE, (tile_m[1], tile_m[0])
    rng = _rng(surface, "shoulder")
    grain = _grain(rng, shape, size, 0.02)
    blotch = _fbm(rng, shape, size, (0.3, 0.6, 1.2, 2.4), (0.4, 0.6, 0.9, 1.0))
    stones = _fbm(rng, shape, size, (0.02,), (1.0,)) > 2.3
    stones = cv2.dilate(stones.astype(np.uint8), np.ones((2, 2), np.uint8)).astype(np.float32)
    value = (1 + 0.07 * blotch) * (1 + 0.22 * grain) + 0.5 * stones
    return _to_srgb8(value, _tint(rng, shape, size, 0.025), surface.shoulder_srgb)


def grass_texture(surface: SurfaceLook, tile_m: tuple[float, float] = Tiling.grass_m) -> np.ndarray:
    """The verge: (256, 1024, 3) uint8 grass, patchy with dry straw and dark clumps, mean ``surface.grass_srgb``."""
    shape, size = GRASS_SHAPE, (tile_m[1], tile_m[0])
    rng = _rng(surface, "grass")
    blades = _fbm(rng, shape, size, (0.015, 0.03, 0.06), (1.0, 0.7, 0.4))
    clumps = _fbm(rng, shape, size, (0.25, 0.5, 1.0), (1.0, 0.8, 0.5))
    dry = _fbm(rng, shape, size, (0.5, 1.0, 2.0, 4.0), (0.5, 0.8, 1.0, 0.8))
    dry_w = np.clip((dry - 0.4) / 1.2, 0, 1)                  # straw where the field is high
    dark_w = np.clip((-clumps - 0.8) / 1.0, 0, 1)              # dark spots where clumps are low
    value = (1 + 0.22 * blades) * (1 - 0.35 * dark_w) * (1 + 0.18 * dry_w)
    straw = np.asarray((1.25, 1.1, 0.85), np.float32)          # straw: redder, less green relative to grass
    tint = (1 - dry_w)[..., None] * np.ones(3, np.float32) + dry_w[..., None] * straw
    tint = tint * _tint(rng, shape, size, 0.03)
    return _to_srgb8(value, tint, surface.grass_srgb)


def pavement_texture(surface: SurfaceLook, street: StreetLook,
                     tile_m: tuple[float, float] = Tiling.pavement_m) -> np.ndarray:
    """Paving slabs of about ``street.slab_m`` (a whole number per tile) with 1-2 cm dark joints, a tone
    per slab, grain and grime: (256, 512, 3) uint8 over ``tile_m`` (along, across; m), mean
    ``street.pavement_srgb``."""
    shape, size = PAVEMENT_SHAPE, (tile_m[1], tile_m[0])
    rng = _rng(surface, "pavement")
    y, x = _grid(shape, size)
    ny, nx = (max(1, round(s / street.slab_m)) for s in size)
    sy, sx = size[0] / ny, size[1] / nx
    slab = rng.uniform(-1, 1, (ny, nx)).astype(np.float32)
    tone = slab[np.minimum((y / sy).astype(int), ny - 1), np.minimum((x / sx).astype(int), nx - 1)]
    joint = np.minimum(np.abs(_wrap(y, sy)), np.abs(_wrap(x, sx)))      # m to the nearest joint
    grain = _grain(rng, shape, size, 0.01)
    grime = _fbm(rng, shape, size, (0.3, 0.6, 1.2), (0.6, 0.8, 1.0))
    value = (1 + 0.05 * tone + 0.06 * grime) * (1 + 0.12 * grain) * (1 - 0.45 * np.exp(-0.5 * (joint / 0.006) ** 2))
    return _to_srgb8(value, _tint(rng, shape, size, 0.02), street.pavement_srgb)


def road_textures(surface: SurfaceLook, lane_width_m: float) -> dict[str, np.ndarray]:
    """The four road textures of ``surface`` (keys as ``road.SURFACE_COLORS``), sized for :func:`road_tiling`."""
    t = road_tiling(surface)
    return {"asphalt": asphalt_texture(surface, lane_width_m, t.asphalt_m),
            "marking": marking_texture(surface, t.marking_m),
            "shoulder": shoulder_texture(surface, t.shoulder_m),
            "grass": grass_texture(surface, t.grass_m)}


# ------------------------------------------------------------------- colours, meshes
def mean_srgb(texture: np.ndarray) -> np.ndarray:
    """(3,) mean sRGB (0..255) of an (H, W, 3) texture: the albedo to shade a textured face with."""
    return texture.reshape(-1, 3).mean(axis=0)


def vertex_rgb(shaded: np.ndarray, albedo_srgb: np.ndarray) -> np.ndarray:
    """Vertex colours of a textured surface: ``shaded`` (..., 3; sRGB 0..1, the shading of the
    texture's mean albedo ``albedo_srgb``, 0..255) divided by that albedo; may exceed 1."""
    return np.asarray(shaded, float) / np.maximum(np.asarray(albedo_srgb, float) / 255.0, 1e-6)


def texture_sampler() -> pyrender.Sampler:
    """Repeat in both directions, bilinear magnification, trilinear (mipmapped) minification."""
    g = pyrender.constants.GLTF
    return pyrender.Sampler(magFilter=g.LINEAR, minFilter=g.LINEAR_MIPMAP_LINEAR, wrapS=g.REPEAT, wrapT=g.REPEAT)


def textured_mesh(triangles: np.ndarray, uv: np.ndarray, vertex_colours: np.ndarray,
                  texture_rgb: np.ndarray) -> pyrender.Mesh:
    """One-primitive pyrender mesh: (F, 3, 3) triangles, (F, 3, 2) texture coordinates, colours
    (F, 3) per face or (F, 3, 3) per vertex (0..1, may exceed 1), and an (H, W, 3) uint8 texture
    as the material's base colour texture (:func:`texture_sampler`)."""
    n = len(triangles)
    colours = np.asarray(vertex_colours, float)
    if colours.ndim == 2:
        colours = np.repeat(colours[:, None, :], 3, axis=1)
    rgba = np.concatenate([colours.reshape(-1, 3), np.ones((3 * n, 1))], axis=1)
    texture = pyrender.Texture(source=np.ascontiguousarray(texture_rgb, dtype=np.uint8), source_channels="RGB",
                               sampler=texture_sampler())
    material = pyrender.MetallicRoughnessMaterial(baseColorFactor=(1.0, 1.0, 1.0, 1.0), baseColorTexture=texture)
    prim = pyrender.Primitive(positions=np.asarray(triangles, np.float32).reshape(-1, 3),
                              texcoord_0=np.asarray(uv, np.float32).reshape(-1, 2),
                              color_0=rgba.astype(np.float32), material=material,
                              mode=pyrender.constants.GLTF.TRIANGLES)
    return pyrender.Mesh([prim])
