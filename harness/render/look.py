"""The look of a render: ``simple`` (flat-shaded boxes, uniform sky) or ``realistic``, and the
structured domain randomisation (Prakash et al. 2019) of the realistic one.

A realistic look is one :class:`LookParams` drawn by :func:`sample_look` from a seed and a family.
Every parameter is drawn within the structure of a motorway scene (the road is a road, trees stand
beside it, the sun is in the sky), not as uniform clutter. Two families:

- ``train``: the family renders for training a detector come from;
- ``heldout``: the same scene structure with disjoint draws: every texture, cloud and roadside
  layout seed comes from a disjoint set (odd against even), and the discrete choices that shape
  the scene most (tree form, median kind) are drawn from variants the training family never uses.

An urban street (``road.street``) adds :class:`StreetLook` (facades, roofs, garden walls, hedges,
street trees; :func:`sample_street`), drawn from a generator of its own: no other field depends on it.
Its facade palette and roof form are disjoint per family as well.

Units: lengths m, angles deg, colours sRGB 0..255, densities per 100 m of road per side.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

Family = Literal["train", "heldout"]
LookName = Literal["simple", "realistic"]

#: Discrete variants per family: the held-out family draws only from variants training never sees.
TREE_FORMS: dict[str, tuple[str, ...]] = {"train": ("broadleaf", "conifer"), "heldout": ("poplar", "shrubby")}
MEDIAN_KINDS: dict[str, tuple[str, ...]] = {"train": ("concrete", "rail"), "heldout": ("concrete_low", "none")}
#: The street frontage's (:mod:`harness.render.street`) discrete variants, disjoint per family likewise.
FACADE_PALETTES: dict[str, tuple[str, ...]] = {"train": ("pastel", "brick"), "heldout": ("white", "stone")}
ROOF_FORMS: dict[str, tuple[str, ...]] = {"train": ("eaves", "gable_front"), "heldout": ("hipped", "flat")}


@dataclass(frozen=True)
class SurfaceLook:
    """Road and verge surfaces."""

    asphalt_srgb: tuple[int, int, int]   # mean tone of the carriageway
    aggregate_contrast: float            # 0..1: grain of the asphalt
    wheel_track_wear: float              # -1..1: wheel tracks darker (<0, oil) or lighter (>0, polished)
    patch_density: float                 # repair patches per 100 m of lane
    seam_spacing_m: float                # tar seams across the road
    marking_wear: float                  # 0 fresh .. 1 nearly gone
    grass_srgb: tuple[int, int, int]     # verge colour (green .. straw)
    shoulder_srgb: tuple[int, int, int]
    texture_seed: int


@dataclass(frozen=True)
class RoadsideLook:
    """What stands beside the road (per side unless stated)."""

    guard_rail: bool                     # W-beam rail on the right verge
    median: str                          # left edge: one of MEDIAN_KINDS
    tree_form: str                       # one of TREE_FORMS
    tree_density: float                  # trees per 100 m
    tree_setback_m: float                # from the outer edge line to the nearest trunks
    bush_density: float
    pole_spacing_m: float                # lighting/sign poles; 0: none
    sign_density: float
    gantry_spacing_m: float              # overhead gantries; 0: none
    building_density: float              # far buildings per 100 m
    hill_height_m: float                 # hills on the horizon
    layout_seed: int


@dataclass(frozen=True)
class StreetLook:
    """The frontage of an urban street (used only where ``road.street`` is set; per side unless stated).
    Ranges are (low, high); shares are of the frontage's length."""

    house_share: float                   # share of plots holding a house (the rest: gardens, drives)
    house_width_m: tuple[float, float]   # along the road, within 6..15
    house_gap_m: float                   # mean gap between neighbouring houses
    storeys: tuple[int, int]             # within 2..4, about 3 m each
    setback_m: tuple[float, float]       # from the pavement's outer edge to the facade, within 0..6
    facade_palette: str                  # one of FACADE_PALETTES
    roof_form: str                       # main roof form: one of ROOF_FORMS (the family's other form mixed in)
    roof_mix: float                      # share of houses with the family's other roof form
    wall_share: float                    # garden walls along the pavement's outer edge
    hedge_share: float
    fence_share: float                   # (the rest: open)
    tree_density: float                  # street trees on the pavement per 100 m
    lamp_spacing_m: float                # lamp posts; 0: none
    sign_density: float                  # sign poles per 100 m
    cabinet_density: float               # street cabinets per 100 m
    kerb_srgb: tuple[int, int, int]
    pavement_srgb: tuple[int, int, int]
    slab_m: float                        # paving slab size (m, square)
    layout_seed: int


@dataclass(frozen=True)
class SkyLook:
    zenith_srgb: tuple[int, int, int]
    horizon_srgb: tuple[int, int, int]
    cloud_cover: float                   # 0 clear .. 1 overcast
    cloud_seed: int


@dataclass(frozen=True)
class SunLook:
    elevation_deg: float
    azimuth_deg: float                   # from +x (along the road) towards +y (left)
    intensity: float                     # shading.shade units
    ambient: float                       # sky light (linear)
    shadow_strength: float               # 0..1: fraction of direct light a shadow removes


@dataclass(frozen=True)
class SensorLook:
    """The camera between the scene's light and the 8-bit frame (:mod:`harness.render.camera_sensor`)."""

    exposure_ev: float                   # relative to the auto-exposure level
    wb_gains: tuple[float, float, float]  # linear R, G, B gains (the white-balance error)
    contrast: float                      # tone-curve slope at mid-grey
    shot_noise: float                    # variance per unit linear signal (8-bit units)
    read_noise: float                    # std, 8-bit levels
    vignetting: float                    # 0..1: corner falloff
    defocus_px: float                    # Gaussian sigma
    jpeg_quality: int                    # per-frame compression with 4:2:0 chroma (the dashcam's codec)


@dataclass(frozen=True)
class VehicleLook:
    dirt: float                          # 0..1
    gloss: float                         # 0..1: the paint's specular share


@dataclass(frozen=True)
class LookParams:
    family: Family
    seed: int
    surface: SurfaceLook
    roadside: RoadsideLook
    sky: SkyLook
    sun: SunLook
    sensor: SensorLook
    vehicle: VehicleLook
    street: StreetLook


def _seed(rng: np.random.Generator, family: Family) -> int:
    """A seed from the family's half of the integers: even for training, odd for held out."""
    return int(rng.integers(0, 2**30)) * 2 + (family == "heldout")


def _rgb(rng: np.random.Generator, base, spread) -> tuple[int, int, int]:
    v = np.asarray(base, float) + rng.uniform(-1, 1) * np.asarray(spread, float)
    return tuple(int(c) for c in np.clip(np.round(v), 0, 255))


def sample_look(seed: int, family: Family = "train") -> LookParams:
    """The realistic look of ``seed`` in ``family`` (deterministic)."""
    rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, 0x100C, family == "heldout"])
    tone = rng.uniform(62, 108)                          # fresh dark to worn pale asphalt
    dry = rng.uniform(0, 1)                              # green to straw verge
    grass = (1 - dry) * np.array([70, 100, 45]) + dry * np.array([150, 140, 95])
    surface = SurfaceLook(
        asphalt_srgb=_rgb(rng, (tone, tone, tone + 2), (4, 4, 4)),
        aggregate_contrast=float(rng.uniform(0.15, 0.5)),
        wheel_track_wear=float(rng.uniform(-0.6, 0.6)),
        patch_density=float(rng.uniform(0, 3)),
        seam_spacing_m=float(rng.choice([0.0, 5.0, 15.0, 30.0])),
        marking_wear=float(rng.uniform(0, 0.6)),
        grass_srgb=_rgb(rng, grass, (10, 10, 8)),
        shoulder_srgb=_rgb(rng, (tone + 15, tone + 12, tone + 8), (8, 8, 8)),
        texture_seed=_seed(rng, family))
    roadside = RoadsideLook(
        guard_rail=bool(rng.uniform() < 0.7),
        median=str(rng.choice(MEDIAN_KINDS[family])),
        tree_form=str(rng.choice(TREE_FORMS[family])),
        tree_density=float(rng.uniform(0, 8)),
        tree_setback_m=float(rng.uniform(4, 15)),
        bush_density=float(rng.uniform(0, 10)),
        pole_spacing_m=float(rng.choice([0.0, 40.0, 60.0])),
        sign_density=float(rng.uniform(0, 0.5)),
        gantry_spacing_m=float(rng.choice([0.0, 0.0, 500.0, 1000.0])),
        building_density=float(rng.uniform(0, 2)),
        hill_height_m=float(rng.uniform(0, 80)),
        layout_seed=_seed(rng, family))
    cover = float(rng.uniform(0, 1))
    sky = SkyLook(zenith_srgb=_rgb(rng, (80 + 90 * cover, 130 + 60 * cover, 210 - 5 * cover), (15, 15, 15)),
                  horizon_srgb=_rgb(rng, (200 + 20 * cover, 212 + 10 * cover, 225), (12, 12, 10)),
                  cloud_cover=cover, cloud_seed=_seed(rng, family))
    elevation = float(rng.uniform(12, 65))
    sun = SunLook(elevation_deg=elevation, azimuth_deg=float(rng.uniform(-180, 180)),
                  intensity=float((1 - 0.7 * cover) * rng.uniform(2.4, 3.4)),
                  ambient=float(rng.uniform(0.4, 0.6)), shadow_strength=float((1 - 0.8 * cover) * rng.uniform(0.6, 0.9)))
    sensor = SensorLook(
        exposure_ev=float(rng.normal(0, 0.25)),
        wb_gains=(float(rng.uniform(0.92, 1.08)), 1.0, float(rng.uniform(0.92, 1.08))),
        contrast=float(rng.uniform(0.9, 1.3)),
        shot_noise=float(rng.uniform(0.02, 0.3)),
        read_noise=float(rng.uniform(0.1, 0.8)),
        vignetting=float(rng.uniform(0.0, 0.4)),
        defocus_px=float(rng.uniform(0.0, 0.8)),
        jpeg_quality=int(rng.integers(55, 92)))
    vehicle = VehicleLook(dirt=float(rng.uniform(0, 0.5)), gloss=float(rng.uniform(0.2, 0.8)))
    return LookParams(family, int(seed), surface, roadside, sky, sun, sensor, vehicle, sample_street(seed, family))


def sample_street(seed: int, family: Family = "train") -> StreetLook:
    """The street frontage of look ``seed`` in ``family``, from its own generator (so that every other
    field of :func:`sample_look` keeps the value it had before streets existed)."""
    rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, 0x57EE7, family == "heldout"])
    w_lo = float(rng.uniform(6, 10))
    s_lo = int(rng.integers(2, 4))
    set_lo = float(rng.uniform(0, 3))
    shares = rng.dirichlet([2.0, 3.0, 1.5, 1.0])          # wall, hedge, fence, open
    pave = rng.uniform(150, 195)
    return StreetLook(
        house_share=float(rng.uniform(0.6, 0.95)),
        house_width_m=(w_lo, float(rng.uniform(w_lo + 2, 15))),
        house_gap_m=float(rng.uniform(1.5, 7)),
        storeys=(s_lo, min(4, s_lo + int(rng.integers(0, 2)))),
        setback_m=(set_lo, float(rng.uniform(set_lo + 1, 6))),
        facade_palette=str(rng.choice(FACADE_PALETTES[family])),
        roof_form=str(rng.choice(ROOF_FORMS[family])),
        roof_mix=float(rng.uniform(0, 0.4)),
        wall_share=float(shares[0]), hedge_share=float(shares[1]), fence_share=float(shares[2]),
        tree_density=float(rng.uniform(1, 10)),
        lamp_spacing_m=float(rng.choice([0.0, 25.0, 35.0])),
        sign_density=float(rng.uniform(0, 2)),
        cabinet_density=float(rng.uniform(0, 2)),
        kerb_srgb=_rgb(rng, (178, 176, 170), (14, 14, 14)),
        pavement_srgb=_rgb(rng, (pave, pave - 3, pave - 8), (10, 10, 10)),
        slab_m=float(rng.choice([0.3, 0.4, 0.6])),
        layout_seed=_seed(rng, family))


def sun_direction_w(sun: SunLook) -> np.ndarray:
    """Unit direction sunlight travels in the world frame W (X along the road, Y left, Z up) for a sun at
    ``sun.elevation_deg`` above the horizon and ``sun.azimuth_deg`` from +X towards +Y."""
    e, a = np.radians(sun.elevation_deg), np.radians(sun.azimuth_deg)
    return -np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
