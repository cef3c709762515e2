"""Static road geometry: asphalt, lane markings, shoulders and grass, as flat rectangles.

All surfaces lie in the ground plane and tile it without overlap (a dashed line's
gaps are asphalt rectangles), so nothing z-fights. Road frame (x along the road
from 0 to ``length_m``, y to the right, lane i centred at y = i * lane_width).
Lane boundary i (0..lanes) is the line y = (i - 0.5) * lane_width; a marking of
``width_m`` is centred on it. Inner boundaries are dashed: stripes of
``stripe_length_m`` starting at x = k * period_m; the outer edges are solid when
``solid_edges`` (else asphalt). Shoulders extend ``shoulder_width_m`` beyond each
edge line's centre (at least to its outer side); grass beyond, and before/after
the road's ends.

An urban street (``road.street``): the shoulders are parking strips of asphalt, and beyond each a
``pavement`` strip ``KERB_WIDTH_M + street.pavement_m`` wide (the kerb, :mod:`harness.render.street`,
stands on its inner ``KERB_WIDTH_M``) before the grass.

With a vertical profile (:mod:`harness.world.road_profile`) every rectangle is cut across the road at
the profile's sample points (1 m apart inside each vertical curve) and each vertex lifted to
``z(x)``, so the surfaces bend with the road and still tile it.

With a horizontal plan (:mod:`harness.world.road_plan`) every rectangle is also cut across the road
``PLAN_STEP_M`` apart over each curve and each vertex ``(x, y)`` moved to ``plan.to_plane(x, y)``;
the grass then reaches ``min(GRASS_EXTENT_M, 0.5 R_min)`` beside the road, so that on the inside
of the tightest curve it stops before the centre of curvature, where the mapping would fold.

:func:`road_surface_uv` gives the same triangles with texture coordinates from the road frame
(:class:`Tiling`; the textures are :mod:`harness.render.textures`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import trimesh

from harness.world.road_plan import RoadPlan
from harness.world.road_profile import RoadProfile
from harness.world.scenario import Road

GRASS_EXTENT_M = 2000.0
PROFILE_STEP_M = 1.0
"""Spacing (m) of the cuts across the road inside a vertical curve."""
PLAN_STEP_M = 2.0
"""Spacing (m) of the cuts across the road over a horizontal curve: a chord leaves the arc by
``step^2 / (8 R)``, 1.7 mm at R = 300 m (3.3 mm at the inner grass edge, R / 2 from the centre)."""

SURFACE_COLORS = {  # RGB 0..255
    "asphalt": (60, 60, 62),
    "marking": (235, 235, 228),
    "shoulder": (112, 106, 96),
    "grass": (66, 96, 44),
    "pavement": (160, 157, 150),
}
KERB_WIDTH_M, KERB_HEIGHT_M = 0.15, 0.12
"""A street's kerb (m): across the road and above it, at the parking strip's outer edge."""


def road_rectangles(road: Road, grass_m: float = GRASS_EXTENT_M) -> dict[str, np.ndarray]:
    """Road-frame rectangles ``(K, 4)`` rows ``[x0, x1, y0, y1]`` (m) per surface kind; grass
    ``grass_m`` wide beside the road and before/after its ends."""
    m = road.markings
    lw, half = road.lane_width_m, road.markings.width_m / 2
    length = road.length_m
    bounds = (np.arange(road.lanes + 1) - 0.5) * lw
    y_left, y_right = bounds[0], bounds[-1]
    out_l = y_left - max(road.shoulder_width_m, half)
    out_r = y_right + max(road.shoulder_width_m, half)
    rects: dict[str, list] = {k: [] for k in SURFACE_COLORS}

    # Lanes (between marking strips) and the solid/absent edge lines.
    for b0, b1 in zip(bounds[:-1], bounds[1:]):
        rects["asphalt"].append([0.0, length, b0 + half, b1 - half])
    edge_kind = "marking" if m.solid_edges else "asphalt"
    for yb in (y_left, y_right):
        rects[edge_kind].append([0.0, length, yb - half, yb + half])

    # Dashed inner lines: stripes at [k P, k P + S], asphalt gaps between.
    starts = np.arange(0.0, length, m.period_m)
    s0, s1 = starts, np.minimum(starts + m.stripe_length_m, length)
    g0, g1 = s1, np.minimum(starts + m.period_m, length)
    keep = g1 > g0
    for yb in bounds[1:-1]:
        for x0, x1 in zip(s0, s1):
            rects["marking"].append([x0, x1, yb - half, yb + half])
        for x0, x1 in zip(g0[keep], g1[keep]):
            rects["asphalt"].append([x0, x1, yb - half, yb + half])

    # Shoulders (a street's parking strips and pavements), then grass all around.
    strip = "shoulder" if road.street is None else "asphalt"
    rects[strip] += [[0.0, length, out_l, y_left - half], [0.0, length, y_right + half, out_r]]
    if road.street is not None:
        walk = KERB_WIDTH_M + road.street.pavement_m
        rects["pavement"] += [[0.0, length, out_l - walk, out_l], [0.0, length, out_r, out_r + walk]]
        out_l, out_r = out_l - walk, out_r + walk
    g = grass_m
    rects["grass"] += [[-g, length + g, out_l - g, out_l], [-g, length + g, out_r, out_r + g],
                       [-g, 0.0, out_l, out_r], [length, length + g, out_l, out_r]]
    result = {}
    for k, v in rects.items():
        a = np.asarray(v, dtype=float).reshape(-1, 4)
        result[k] = a[(a[:, 1] > a[:, 0]) & (a[:, 3] > a[:, 2])]
    return result


def split_along(rects: np.ndarray, xs: np.ndarray) -> np.ndarray:
    """Rectangles ``[x0, x1, y0, y1]`` cut at every ``x`` of ``xs`` strictly inside them."""
    xs = np.sort(np.asarray(xs, dtype=float))
    out = []
    for x0, x1, y0, y1 in rects:
        edges = np.r_[x0, xs[(xs > x0) & (xs < x1)], x1]
        out.append(np.stack([edges[:-1], edges[1:], np.full(len(edges) - 1, y0), np.full(len(edges) - 1, y1)], -1))
    return np.concatenate(out, axis=0) if out else rects


def rectangles_trimesh(rects: np.ndarray, color: tuple[int, int, int],
                       profile: RoadProfile | None = None, plan: RoadPlan | None = None) -> trimesh.Trimesh:
    """Road-frame rectangles -> one upward-facing ground mesh in the world frame W (Y = -y),
    level or following ``profile``, straight or following ``plan``."""
    if profile is not None:
        rects = split_along(rects, profile.curved_x(PROFILE_STEP_M))
    if plan is not None:
        rects = split_along(rects, plan.curved_x(PLAN_STEP_M))
    x0, x1, y0, y1 = rects.T
    # Corners in W, counter-clockwise seen from above (+Z): Y = -y.
    corners = np.stack([np.stack([x0, -y1], -1), np.stack([x1, -y1], -1),
                        np.stack([x1, -y0], -1), np.stack([x0, -y0], -1)], axis=1)
    verts = np.concatenate([corners.reshape(-1, 2), np.zeros((corners.size // 2, 1))], axis=1)
    if profile is not None:
        verts[:, 2] = profile.z(verts[:, 0])
    if plan is not None:
        p = plan.to_plane(verts[:, 0], -verts[:, 1])
        verts[:, 0], verts[:, 1] = p[:, 0], -p[:, 1]
    base = 4 * np.arange(len(rects))[:, None]
    faces = np.concatenate([base + [0, 1, 2], base + [0, 2, 3]], axis=0)
    mesh = trimesh.Trimesh(verts, faces, process=False)
    mesh.visual.face_colors = (*color, 255)
    return mesh


def _road_pieces(road: Road, plan: RoadPlan | None) -> dict[str, np.ndarray]:
    """The rectangles of :func:`road_trimeshes` per kind, with a plan cut at its curves."""
    if plan is None:
        return road_rectangles(road)
    # every piece over a curve cut at every rectangle's ends too: no T-junction opens a crack
    rects = road_rectangles(road, min(GRASS_EXTENT_M, 0.5 * plan.min_radius()))
    curved = plan.curved_x(PLAN_STEP_M)
    edges = np.unique(np.concatenate([r[:, :2].ravel() for r in rects.values()]))
    cuts = np.r_[curved, edges[(edges > curved[0]) & (edges < curved[-1])]]
    return {k: split_along(r, cuts) for k, r in rects.items()}


def road_trimeshes(road: Road, profile: RoadProfile | None = None,
                   plan: RoadPlan | None = None) -> dict[str, trimesh.Trimesh]:
    """One merged W-frame mesh per surface kind (asphalt, marking, shoulder, grass; a street's pavement)."""
    rects = _road_pieces(road, plan)
    return {k: rectangles_trimesh(r, SURFACE_COLORS[k], profile, plan) for k, r in rects.items() if len(r)}


# ----------------------------------------------------------------- texture coordinates
@dataclass(frozen=True)
class Tiling:
    """Texture tiles in the road frame (m): ``(along, across)`` per kind; the asphalt's across is
    one lane (v = (y + lane_width / 2) / lane_width, integer at lane boundaries). Lane i's asphalt
    runs shifted along the road by :func:`lane_shift_m` (a multiple of ``asphalt_shift_m`` when > 0)
    and, in odd lanes, mirrored along the road: ``u = +-(x + shift) / asphalt_m``; both keep seams
    at multiples of ``asphalt_shift_m`` straight across the road while a lane's patches stand
    elsewhere than its neighbour's."""

    asphalt_m: float = 16.0
    asphalt_shift_m: float = 0.0
    marking_m: tuple[float, float] = (4.0, 0.5)
    shoulder_m: tuple[float, float] = (8.0, 4.0)
    grass_m: tuple[float, float] = (16.0, 4.0)
    pavement_m: tuple[float, float] = (4.8, 2.4)


def lane_shift_m(lane: np.ndarray, tiling: Tiling) -> np.ndarray:
    """Along-road shift (m, in [0, asphalt_m)) of lane ``lane``'s asphalt texture: the golden-ratio
    sequence of the tile, rounded to whole ``asphalt_shift_m`` (seams stay straight across); lane 0: 0."""
    tile, q = tiling.asphalt_m, tiling.asphalt_shift_m
    shift = (np.asarray(lane, float) * (math.sqrt(5) - 1) / 2) % 1.0 * tile
    if q > 0:
        shift = np.round(shift / q) * q
    return shift % tile


def _rect_uv(rects: np.ndarray, kind: str, road: Road, tiling: Tiling) -> np.ndarray:
    """(R, 4, 2) texture coordinates of the corners of road-frame rectangles in
    :func:`rectangles_trimesh`'s corner order, from road-frame x, y."""
    x0, x1, y0, y1 = rects.T
    xs = np.stack([x0, x1, x1, x0], axis=1)
    ys = np.stack([y1, y1, y0, y0], axis=1)
    if kind == "asphalt":
        lw = road.lane_width_m
        lane = np.clip(np.floor((y0 + y1) / (2 * lw) + 0.5), 0, road.lanes - 1)
        sign = np.where(lane % 2 == 1, -1.0, 1.0)[:, None]
        u = sign * (xs + lane_shift_m(lane, tiling)[:, None]) / tiling.asphalt_m
        v = (ys + lw / 2) / lw
    else:
        along, across = getattr(tiling, f"{kind}_m")
        u, v = xs / along, ys / across
    return np.stack([u, v], axis=-1)


def road_surface_uv(road: Road, profile: RoadProfile | None = None, plan: RoadPlan | None = None,
                    tiling: Tiling = Tiling()) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per surface kind: the W-frame triangles (F, 3, 3) of :func:`road_trimeshes` (the same
    triangles in the same order) and their per-vertex texture coordinates (F, 3, 2), taken from
    the road-frame coordinates before the plan's mapping, so textures run along the road."""
    out = {}
    for kind, rects in _road_pieces(road, plan).items():
        if not len(rects):
            continue
        if profile is not None:                                # the cuts rectangles_trimesh makes
            rects = split_along(rects, profile.curved_x(PROFILE_STEP_M))
        if plan is not None:
            rects = split_along(rects, plan.curved_x(PLAN_STEP_M))
        tm = rectangles_trimesh(rects, SURFACE_COLORS[kind], profile, plan)
        corner_uv = _rect_uv(rects, kind, road, tiling)
        uv = np.concatenate([corner_uv[:, [0, 1, 2]], corner_uv[:, [0, 2, 3]]], axis=0)
        out[kind] = (tm.vertices[tm.faces], uv)
    return out
