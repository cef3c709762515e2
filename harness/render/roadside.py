"""What stands beside the road in the realistic look, as static geometry (pure numpy/trimesh).

:func:`harness.render.scenery.roadside_geometry` turns a :class:`~harness.render.look.RoadsideLook` into three sets of
triangles in the world frame W (X along the road, Y = -y to the left, Z up; m):

- ``occluders``: what can stand between the camera and a vehicle: the W-beam guard rail on the
  right verge, the median barrier on the left edge (``concrete`` jersey 0.81 m, ``concrete_low``
  0.5 m, a double ``rail``, ``none``), trees (``broadleaf``: trunk + lumpy crown of perturbed
  icospheres; ``conifer``: trunk + three stacked cones; ``poplar``: tall narrow ellipsoids;
  ``shrubby``: low multi-stem), bushes, lighting poles with arms, signs on posts and overhead
  gantries (legs beyond the shoulders, beam and plates >= 5.5 m above the road);
- ``far``: buildings 150-800 m from the road and a ring of hills a few km away whose ridge sits
  near the horizon (never in front of a vehicle that matters);
- ``shadows``: flat ground-level polygons (2-3 cm above the ground) of the shadows the occluders
  cast for sunlight travelling along ``sun_w``.

Placement. Road frame (x along the road, y to the right; lane i centred at y = i * lane_width).
The clear band ``[y_left - s - 0.5, y_right + s + 0.5]`` (outer edge lines y_left/right, shoulder
width s; :func:`clear_band`) holds nothing but the gantry beams and their plates (>= 5.5 m up);
objects stand along x in [-300 m, length + 300 m]. A long object (rail, median) is swept along
the road and every vertex mapped through the plan and profile, so it bends with them; a compact
object (tree, pole, sign, gantry, building) is placed rigidly at its anchor's plane position,
heading ``theta(x)`` and ground height ``z(x)``; trunks and posts reach 0.3-0.5 m into the ground
so a slope under them leaves no gap. With a plan, compact objects stay within ``0.5 R_min`` of the
road (where :mod:`harness.render.road`'s grass ends).

A street (``road.street``): the clear band is the carriageway and the parking strips (the shoulders),
no margin; no rail, median, poles, signs or gantries; kerbs, pavements' furniture and the frontage of
:mod:`harness.render.street` instead, and the verge's trees and bushes only ``STREET_TREES_BEYOND_M``
behind the pavements.

Every object's size and colour is drawn from ``layout_seed`` (one generator per kind, so turning
one kind off leaves the others where they were): same inputs, same geometry. Faces are wound
counter-clockwise seen from outside (the renderer culls back faces); albedo is sRGB 0..255.

Shadows. Each part (a trunk, a crown lump, a post, a rail segment, ...) is projected along
``sun_w`` onto the ground (exactly on a profile: secant iterations along each ray) and the 2-D
convex hull of its projection, fanned into triangles, lifted to the ground + 2-3 cm, is its
shadow; a tree's lumps give the lumpy blob a real crown casts. Part i of n lies at
``3 cm - 1 cm * i / n`` above the ground, in array order: drawn in order with depth writes and a
``GL_LESS`` test, overlapping shadows darken a pixel once.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import cv2
import numpy as np
import trimesh

from harness.render.look import RoadsideLook
from harness.world.road_plan import RoadPlan
from harness.world.road_profile import RoadProfile
from harness.world.scenario import Road

MARGIN_M = 300.0
"""Objects stand this far (m) before the road's start and after its end too."""
CLEAR_MARGIN_M = 0.5
"""Beyond the shoulders (m): nothing but gantry beams stands closer to the carriageway."""
GANTRY_CLEARANCE_M = 5.5
"""Lowest point (m above the road) of a gantry's beam and plates."""
SHADOW_LIFT_M = (0.02, 0.03)
"""Height range (m) of the shadow polygons above the ground."""
HILL_MAX_DISTANCE_M = 5500.0
"""The hill ridge is at most this far (m) from any camera on the road (inside ZFAR 6000 m and the
sky dome's radius, :data:`harness.render.sky.SKY_RADIUS_M`), roads up to 1.7 km long; longer
roads keep the ridge 2 km from the road and the ends of its ring may pass ZFAR."""
STATION_STEP_M = 5.0
"""Spacing (m) of a swept object's cross-sections on the straight, level road (2.5 m over curves)."""
MIN_SUN_ELEVATION_DEG = 3.0
"""No shadows below this sun elevation."""
MAX_BUILDINGS = 700
"""At most this many buildings (16 triangles each): with the hills, the far set stays under 15k."""
KINDS = ("rail", "median", "tree", "bush", "pole", "sign", "gantry", "building", "hill",
         "kerb", "house", "facade", "boundary", "street_tree", "furniture")
"""Kinds of faces; the last six are a street's (:mod:`harness.render.street`)."""


@dataclass(frozen=True)
class Faces:
    """Flat-shaded triangles: ``triangles`` (F, 3, 3) W, m; ``albedo`` (F, 3) uint8 sRGB;
    ``normals`` (F, 3) unit, outward (the counter-clockwise side); ``kind`` (F,) index into KINDS."""

    triangles: np.ndarray
    albedo: np.ndarray
    normals: np.ndarray
    kind: np.ndarray

    def __len__(self) -> int:
        return len(self.triangles)

    def of(self, kind: str) -> "Faces":
        """The faces of one kind of :data:`KINDS`."""
        keep = self.kind == KINDS.index(kind)
        return Faces(self.triangles[keep], self.albedo[keep], self.normals[keep], self.kind[keep])


@dataclass(frozen=True)
class RoadsideGeometry:
    """``occluders`` and ``far`` faces, and ``shadows`` (S, 3, 3) W ground-level triangles (facing up)."""

    occluders: Faces
    far: Faces
    shadows: np.ndarray


# --------------------------------------------------------------------------- the ground
class Ground:
    """Maps road coordinates to W (road ``(x, y)`` at height ``h`` above the road surface there)
    and back (:meth:`road_x`, for road ``x`` within ``x_range`` m and 500 m beyond)."""

    def __init__(self, profile: RoadProfile | None = None, plan: RoadPlan | None = None,
                 x_range: tuple[float, float] = (-MARGIN_M, 5000.0)) -> None:
        self.profile, self.plan, self.x_range = profile, plan, x_range

    def z(self, x) -> np.ndarray:
        """Road height (m) at road ``x`` (the same across the road)."""
        x = np.asarray(x, dtype=float)
        return np.zeros_like(x) if self.profile is None else self.profile.z(x)

    def bend(self, x, yl, h) -> np.ndarray:
        """(..., 3) W points of road ``x``, ``yl`` = -y (m, left), height ``h`` above the road."""
        x, yl, h = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (x, yl, h)))
        if self.plan is None:
            px, py = x, yl
        else:
            p = self.plan.to_plane(x, -yl)
            px, py = p[..., 0], -p[..., 1]
        return np.stack([px, py, self.z(x) + h], axis=-1)

    def place(self, local: np.ndarray, x0, yl0) -> np.ndarray:
        """(n, ..., 3) object-frame points (a along the road, b left, h up; m) -> W, object i
        anchored on the ground at road ``(x0[i], -yl0[i])`` turned with the road's heading there."""
        x0, yl0 = np.asarray(x0, dtype=float), np.asarray(yl0, dtype=float)
        pos = self.bend(x0, yl0, 0.0)
        yaw = np.zeros_like(x0) if self.plan is None else -self.plan.theta(x0)
        shape = (len(x0),) + (1,) * (local.ndim - 2)
        c, s = np.cos(yaw).reshape(shape), np.sin(yaw).reshape(shape)
        a, b, h = local[..., 0], local[..., 1], local[..., 2]
        return np.stack([c * a - s * b + pos[:, 0].reshape(shape), s * a + c * b + pos[:, 1].reshape(shape),
                         h + pos[:, 2].reshape(shape)], axis=-1)

    @functools.cached_property
    def _line(self):
        """Reference line samples 1 m apart: KD-tree of W positions, x, W tangent, curvature."""
        from scipy.spatial import cKDTree

        x = np.arange(self.x_range[0] - 500.0, self.x_range[1] + 500.0, 1.0)
        c = self.plan.centre(x)
        th = self.plan.theta(x)
        return cKDTree(np.stack([c[:, 0], -c[:, 1]], -1)), x, np.stack([np.cos(th), -np.sin(th)], -1), \
            self.plan.curvature(x)

    def road_frame(self, xy: np.ndarray, x_guess: np.ndarray | None = None,
                   steps: int = 2) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Road ``x`` (m) of W horizontal points ``xy`` (N, 2), and ``dx/dX``, ``dx/dY`` there: from
        the reference-line sample nearest ``x_guess`` (or, without one, nearest the point), steps
        along the sample's tangent, ``x = x_k + (p - C_k) . T_k / (1 - kappa_k y)`` (within 1 m,
        the error is ~ kappa * 0.25 m)."""
        xy = np.asarray(xy, dtype=float)
        if self.plan is None:
            return xy[:, 0].copy(), np.ones(len(xy)), np.zeros(len(xy))
        tree, xs, tangent, kappa = self._line
        if x_guess is None:
            k = tree.query(xy)[1]
        else:
            k = np.clip(np.round(np.asarray(x_guess, dtype=float) - xs[0]).astype(np.int64), 0, len(xs) - 1)
        for step in range(steps):
            d = xy - tree.data[k]
            t = tangent[k]
            y = -(d[:, 0] * -t[:, 1] + d[:, 1] * t[:, 0])        # road y (right) of the point
            stretch = np.maximum(1 - kappa[k] * y, 0.2)
            x = xs[k] + np.sum(d * t, axis=1) / stretch
            if step < steps - 1:
                k = np.clip(np.round(x - xs[0]).astype(np.int64), 0, len(xs) - 1)
        return x, t[:, 0] / stretch, t[:, 1] / stretch

    @functools.cached_property
    def _tables(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Road height and slope every 0.5 m over ``x_range`` and 500 m beyond (with every break
        point of the profile a node): linear between nodes to ~1e-5 m."""
        x = np.union1d(np.arange(self.x_range[0] - 500.0, self.x_range[1] + 500.0, 0.5), self.profile.breakpoints())
        return x, self.profile.z(x), self.profile.slope(x)

    def z_slope(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Road height (m) and slope at road ``x`` from the tables (the profile's own beyond them)."""
        xs, zs, gs = self._tables
        x = np.asarray(x, dtype=float)
        z, g = np.interp(x, xs, zs), np.interp(x, xs, gs)
        out = (x < xs[0]) | (x > xs[-1])
        if out.any():
            z[out], g[out] = self.profile.z(x[out]), self.profile.slope(x[out])
        return z, g

    def height(self, xy: np.ndarray, x_guess: np.ndarray | None = None) -> np.ndarray:
        """Ground height (m) under W horizontal points ``xy`` (N, 2)."""
        if self.profile is None:
            return np.zeros(len(xy))
        return self.z_slope(self.road_frame(xy, x_guess)[0])[0]


def clear_band(road: Road) -> tuple[float, float]:
    """Road-frame ``y`` range (m) kept clear: the carriageway, the shoulders and 0.5 m beyond; on a street
    the carriageway and the parking strips (the shoulders), whose outer edges the kerbs stand on."""
    y_left, y_right = -0.5 * road.lane_width_m, (road.lanes - 0.5) * road.lane_width_m
    margin = CLEAR_MARGIN_M if road.street is None else 0.0
    return y_left - road.shoulder_width_m - margin, y_right + road.shoulder_width_m + margin


# --------------------------------------------------------------------------- primitives
# Object frame: a along the road, b to the left, h up (right-handed like W). Each returns
# (verts (n, V, 3), faces (F, 3)) with the faces counter-clockwise seen from outside.

@functools.cache
def unit_sphere(subdivisions: int) -> tuple[np.ndarray, np.ndarray]:
    s = trimesh.creation.icosphere(subdivisions=subdivisions)
    return np.asarray(s.vertices, dtype=float), np.asarray(s.faces, dtype=np.int64)


@functools.cache
def _cube(bottom: bool) -> tuple[np.ndarray, np.ndarray]:
    b = trimesh.creation.box()
    v, f = np.asarray(b.vertices, dtype=float), np.asarray(b.faces, dtype=np.int64)
    if not bottom:
        f = f[~np.all(v[f][:, :, 2] < 0, axis=1)]
    return v, f


def boxes(centre: np.ndarray, size: np.ndarray, bottom: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned boxes (n, 3) centres and sizes; without the bottom face unless ``bottom``."""
    v, f = _cube(bottom)
    return centre[:, None, :] + size[:, None, :] * v, f


def frustums(p0: np.ndarray, p1: np.ndarray, r0: np.ndarray, r1: np.ndarray, sides: int,
             top: bool = True, bottom: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Truncated cones from ``p0`` (radius ``r0``) to ``p1`` (``r1``), (n, 3) and (n,) each;
    ``r1 = 0`` gives a cone (its apex duplicated, the degenerate faces left out)."""
    axis = p1 - p0
    axis = axis / np.linalg.norm(axis, axis=1, keepdims=True)
    helper = np.where(np.abs(axis[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
    u = np.cross(axis, helper)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(axis, u)
    phi = 2 * np.pi * np.arange(sides) / sides
    ring = np.cos(phi)[None, :, None] * u[:, None] + np.sin(phi)[None, :, None] * v[:, None]
    verts = np.concatenate([p0[:, None] + r0[:, None, None] * ring, p1[:, None] + r1[:, None, None] * ring,
                            p0[:, None], p1[:, None]], axis=1)
    i, j = np.arange(sides), (np.arange(sides) + 1) % sides
    cone = bool(np.all(np.asarray(r1) == 0))
    faces = [np.stack([i, j, sides + j], -1)]
    if not cone:
        faces.append(np.stack([i, sides + j, sides + i], -1))
        if top:
            faces.append(np.stack([np.full(sides, 2 * sides + 1), sides + i, sides + j], -1))
    if bottom:
        faces.append(np.stack([np.full(sides, 2 * sides), j, i], -1))
    return verts, np.concatenate(faces)


def blobs(rng: np.random.Generator, centre: np.ndarray, radii: np.ndarray, subdivisions: int,
          jitter: float) -> tuple[np.ndarray, np.ndarray]:
    """Ellipsoids (n, 3) centres and semi-axes, each vertex moved radially by up to ``jitter``
    (fraction) at random and the whole turned about the vertical at random: lumps of foliage."""
    v, f = unit_sphere(subdivisions)
    n = len(centre)
    scale = 1 + rng.uniform(-jitter, jitter, (n, len(v), 1))
    yaw = rng.uniform(0, 2 * np.pi, n)[:, None]
    c, s = np.cos(yaw), np.sin(yaw)
    p = v[None] * scale
    p = np.stack([c * p[..., 0] - s * p[..., 1], s * p[..., 0] + c * p[..., 1], p[..., 2]], axis=-1)
    return centre[:, None, :] + radii[:, None, :] * p, f


# --------------------------------------------------------------------------- assembly
@dataclass
class Batch:
    """n instances of one part: W vertices (n, V, 3), template faces (F, 3), albedo (n, F, 3)."""

    verts: np.ndarray
    faces: np.ndarray
    albedo: np.ndarray
    kind: str


def albedo_draw(rng: np.random.Generator, base, spread, n: int, n_faces: int, face_jitter: float = 0.0) -> np.ndarray:
    """(n, F, 3) colours: ``base`` +- ``spread`` per instance (one draw scales all three channels
    and a smaller one tints), times 1 +- ``face_jitter`` per face."""
    base, spread = np.asarray(base, float), np.asarray(spread, float)
    col = base + rng.uniform(-1, 1, (n, 1)) * spread + rng.uniform(-0.35, 0.35, (n, 3)) * spread
    col = np.repeat(col[:, None, :], n_faces, axis=1)
    if face_jitter:
        col = col * (1 + rng.uniform(-face_jitter, face_jitter, (n, n_faces, 1)))
    return col


def faces_of(batches: list[Batch]) -> Faces:
    tris, alb, kind = [], [], []
    for b in batches:
        if len(b.verts) == 0:
            continue
        t = b.verts[:, b.faces].reshape(-1, 3, 3)
        tris.append(t)
        alb.append(b.albedo.reshape(-1, 3))
        kind.append(np.full(len(t), KINDS.index(b.kind), dtype=np.int8))
    if not tris:
        z = np.zeros((0, 3))
        return Faces(np.zeros((0, 3, 3)), z.astype(np.uint8), z, np.zeros(0, np.int8))
    t, a, k = np.concatenate(tris), np.concatenate(alb), np.concatenate(kind)
    e1, e2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    n = np.stack([e1[:, 1] * e2[:, 2] - e1[:, 2] * e2[:, 1], e1[:, 2] * e2[:, 0] - e1[:, 0] * e2[:, 2],
                  e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]], axis=-1)
    norm = np.sqrt(np.einsum("ij,ij->i", n, n))
    ok = norm > 1e-12
    return Faces(t[ok], np.clip(np.round(a[ok]), 0, 255).astype(np.uint8), n[ok] / norm[ok, None], k[ok])


@dataclass(frozen=True)
class Layout:
    """Where things may stand: road x range and the clear band's edges in yl = -y."""

    x0: float
    x1: float
    edge_left: float      # yl of the band's left edge (> 0)
    edge_right: float     # yl of the band's right edge (< 0)
    line_gap: float       # from an outer edge line to the band's edge (shoulder + 0.5 m)
    max_offset: float     # farthest a compact object may stand from the band

    def yl(self, side: np.ndarray, d: np.ndarray) -> np.ndarray:
        """yl of points ``d`` (m) beyond the band on ``side`` (+1 left, -1 right)."""
        return np.where(side > 0, self.edge_left + d, self.edge_right - d)


def _xs_along(rng: np.random.Generator, lay: Layout, per_100m: float, group_mean: float,
              spread_m: float) -> np.ndarray:
    """Road x of objects at ``per_100m`` on average, in groups of ``group_mean`` spread ``spread_m``."""
    span = lay.x1 - lay.x0
    n_groups = rng.poisson(max(per_100m, 0.0) * span / 100.0 / group_mean)
    sizes = 1 + rng.poisson(group_mean - 1, n_groups)
    centres = rng.uniform(lay.x0, lay.x1, n_groups)
    x = np.repeat(centres, sizes) + rng.normal(0, spread_m, int(sizes.sum()))
    return np.sort(x[(x >= lay.x0) & (x <= lay.x1)])


def stations(ground: Ground, x0: float, x1: float) -> np.ndarray:
    xs = [np.linspace(x0, x1, int(math.ceil((x1 - x0) / STATION_STEP_M)) + 1)]
    for part in (ground.plan, ground.profile):
        if part is not None:
            xs.append(part.curved_x(STATION_STEP_M / 2))
    xs = np.unique(np.concatenate(xs))
    return xs[(xs >= x0) & (xs <= x1)]


def sweep(ground: Ground, xs: np.ndarray, section: np.ndarray, closed: bool) -> tuple[np.ndarray, np.ndarray]:
    """A cross-section (P, 2) of (yl, h) swept along road stations ``xs`` (m), every vertex bent
    with the road: per segment (m - 1, 2P, 3) W vertices and faces (outward; ``closed=False``
    leaves out the last-to-first edge, e.g. the bottom)."""
    sec = np.asarray(section, dtype=float)
    y, h = sec[:, 0], sec[:, 1]
    if np.sum(y * np.roll(h, -1) - np.roll(y, -1) * h) > 0:   # make it clockwise in (yl, h)
        sec = sec[::-1]
    p = len(sec)
    pts = ground.bend(xs[:, None], sec[None, :, 0], sec[None, :, 1])           # (m, P, 3)
    seg = np.concatenate([pts[:-1], pts[1:]], axis=1)                           # (m-1, 2P, 3)
    i = np.arange(p if closed else p - 1)
    j = (i + 1) % p
    faces = np.concatenate([np.stack([i, p + i, p + j], -1), np.stack([i, p + j, j], -1)])
    return seg, faces


# --------------------------------------------------------------------------- the objects
# W-beam (d beyond the band, h): road-facing bumps at d = 0.25, 0.31 m deep section.
_W_BEAM = np.array([[0.33, 0.45], [0.25, 0.525], [0.31, 0.605], [0.25, 0.685], [0.33, 0.76], [0.36, 0.76],
                    [0.36, 0.45]])
_RAIL_POST_D = (0.36, 0.51)
_JERSEY = np.array([[0.0, -0.05], [0.0, 0.075], [0.18, 0.33], [0.23, 0.81], [0.38, 0.81], [0.43, 0.33],
                    [0.61, 0.075], [0.61, -0.05]])
_JERSEY_AT_D = 0.2


def rail_batches(ground: Ground, lay: Layout, rng: np.random.Generator, side: int, kind: str,
          d0: float, facing_out: bool = False) -> list[Batch]:
    """A W-beam along the whole road on ``side``, its face ``d0`` beyond the band (facing the road,
    or away from it with ``facing_out``), with posts every 4 m behind it."""
    xs = stations(ground, lay.x0, lay.x1)
    d = _W_BEAM[:, 0] if not facing_out else (sum(_RAIL_POST_D) - _W_BEAM[:, 0])   # mirrored about the posts
    yl = lay.yl(np.full(len(d), side), d + d0 - 0.25)
    verts, faces = sweep(ground, xs, np.stack([yl, _W_BEAM[:, 1]], -1), closed=True)
    n = len(verts)
    grey = albedo_draw(rng, (165, 168, 170), (12, 12, 12), 1, 1)[0, 0]
    alb = np.broadcast_to(grey * (1 + rng.uniform(-0.05, 0.05, (n, 1, 1))), (n, len(faces), 3))
    out = [Batch(verts, faces, alb, kind)]
    px = np.arange(lay.x0 + rng.uniform(0, 4), lay.x1, 4.0)
    dc = d0 - 0.25 + sum(_RAIL_POST_D) / 2
    pv, pf = boxes(np.tile([[0.0, 0.0, 0.2]], (len(px), 1)), np.tile([[0.15, _RAIL_POST_D[1] - _RAIL_POST_D[0], 1.0]],
                                                                   (len(px), 1)))
    pv = ground.place(pv, px, lay.yl(np.full(len(px), side), np.full(len(px), dc)))
    out.append(Batch(pv, pf, albedo_draw(rng, (120, 122, 125), (10, 10, 10), len(px), len(pf)), kind))
    return out


def median_batches(ground: Ground, lay: Layout, rng: np.random.Generator, kind: str) -> list[Batch]:
    """The barrier on the left edge, just beyond the left shoulder's clearance."""
    if kind == "none":
        return []
    if kind == "rail":   # two beams back to back on one row of posts
        return rail_batches(ground, lay, rng, +1, "median", 0.25) + rail_batches(ground, lay, rng, +1, "median", 0.25, True)[:1]
    if kind not in ("concrete", "concrete_low"):
        raise ValueError(f"median: unknown kind {kind!r}")
    sec = _JERSEY.copy()
    if kind == "concrete_low":
        sec[:, 1] *= 0.5 / 0.81
    xs = stations(ground, lay.x0, lay.x1)
    yl = lay.yl(np.full(len(sec), 1), sec[:, 0] + _JERSEY_AT_D)
    verts, faces = sweep(ground, xs, np.stack([yl, sec[:, 1]], -1), closed=False)
    n = len(verts)
    tone = albedo_draw(rng, (188, 186, 180), (14, 14, 14), 1, 1)[0, 0]
    alb = np.broadcast_to(tone * (1 + rng.uniform(-0.06, 0.06, (n, 1, 1))), (n, len(faces), 3))
    return [Batch(verts, faces, alb, "median")]


_FOLIAGE = {"broadleaf": ((62, 92, 40), (14, 18, 10)), "conifer": ((38, 62, 40), (8, 12, 8)),
            "poplar": ((70, 98, 44), (12, 16, 10)), "shrubby": ((78, 92, 48), (16, 18, 12))}
_BARK = ((92, 78, 62), (16, 14, 12))


def _both_sides(rng: np.random.Generator, lay: Layout, density: float, *spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Stations ``x`` along the road (``_xs_along``) on the left (+1) then the right (-1) side, and each one's side."""
    xs = [_xs_along(rng, lay, density, *spacing) for _ in (+1, -1)]
    return np.concatenate(xs), np.concatenate([np.full(len(x), side) for x, side in zip(xs, (+1, -1))])


def tree_batches(ground: Ground, lay: Layout, rng: np.random.Generator, look: RoadsideLook,
           right_min_d: float) -> list[Batch]:
    """Trees of ``look.tree_form`` on both sides, ``tree_setback_m`` and more beyond the edge lines."""
    form = look.tree_form
    if form not in _FOLIAGE:
        raise ValueError(f"tree_form: unknown form {form!r}")
    x, side = _both_sides(rng, lay, look.tree_density, 3.0, 7.0)
    n = len(x)
    if n == 0:
        return []
    # Sizes: height H, crown radius rc (the crown's reach from the trunk axis), lumps.
    if form == "broadleaf":
        height = rng.uniform(6, 14, n)
        rc = height * rng.uniform(0.25, 0.34, n)
        n_lumps = 3 if look.tree_density <= 5 else 2        # the triangle budget at dense planting
    elif form == "conifer":
        height = rng.uniform(8, 20, n)
        rc = height * rng.uniform(0.17, 0.22, n)
        n_lumps = 0
    elif form == "poplar":
        height = rng.uniform(14, 24, n)
        rc = rng.uniform(1.2, 2.0, n)
        n_lumps = 2
    else:
        height = rng.uniform(2.5, 5.0, n)
        rc = height * rng.uniform(0.35, 0.5, n)
        n_lumps = 3 if look.tree_density <= 5 else 2
    reach = (1.05 if form == "conifer" else 1.5) * rc      # the crown's farthest lateral reach
    d_line = look.tree_setback_m + rng.exponential(6.0, n)
    d = np.maximum(d_line - lay.line_gap, reach + 0.4)
    d = np.where(side < 0, np.maximum(d, right_min_d + reach), d)
    keep = d + reach <= lay.max_offset
    x, side, d, height, rc = x[keep], side[keep], d[keep], height[keep], rc[keep]
    n = len(x)
    if n == 0:
        return []
    yl = lay.yl(side, d)
    zero = np.zeros(n)
    out = []

    def add(verts, faces, base, spread, jitter, kind="tree"):
        out.append(Batch(ground.place(verts, x, yl), faces, albedo_draw(rng, base, spread, n, len(faces), jitter),
                          kind))

    if form == "conifer":
        h0 = rng.uniform(0.8, 2.0, n)
        trunk_top = h0 + 0.3 * (height - h0)
        v, f = frustums(np.stack([zero, zero, zero - 0.5], -1), np.stack([zero, zero, trunk_top], -1),
                        0.012 * height + 0.08, 0.008 * height + 0.05, 6, top=False)
        add(v, f, *_BARK, 0.05)
        base, spread = _FOLIAGE[form]
        tint = rng.uniform(0.85, 1.15, (n, 1))
        for lo, hi, r in ((0.0, 0.55, 1.0), (0.3, 0.8, 0.72), (0.55, 1.0, 0.45)):
            v, f = frustums(np.stack([zero, zero, h0 + lo * (height - h0)], -1),
                            np.stack([zero, zero, h0 + hi * (height - h0)], -1), rc * r, zero, 8, bottom=True)
            alb = albedo_draw(rng, base, spread, n, len(f), 0.06) * tint[:, :, None]
            out.append(Batch(ground.place(v, x, yl), f, alb, "tree"))
        return out

    base, spread = _FOLIAGE[form]
    if form == "shrubby":    # stems from a common root leaning outward, a small crown on each
        stems = n_lumps
        ang = rng.uniform(0, 2 * np.pi, n)[:, None] + 2 * np.pi * np.arange(stems) / stems
        lean = rc[:, None] * rng.uniform(0.4, 0.7, (n, stems))
        tops = np.stack([lean * np.cos(ang), lean * np.sin(ang),
                         height[:, None] * rng.uniform(0.55, 0.8, (n, stems))], -1)
        for k in range(stems):
            v, f = frustums(np.stack([zero, zero, zero - 0.3], -1), tops[:, k], zero + 0.07, zero + 0.04, 4, top=False)
            add(v, f, *_BARK, 0.05)
        lump_c = tops + np.stack([zero, zero, 0.25 * rc], -1)[:, None]
        lump_r = np.repeat((rc * 0.55)[:, None, None], stems, 1) * rng.uniform(0.8, 1.2, (n, stems, 1)) * [1, 1, 0.8]
    else:
        if form == "broadleaf":   # the crown from 25-40 % of the height to the top
            half_z = height * (1 - rng.uniform(0.25, 0.4, n)) / 2
            crown_h = height - half_z
        else:
            crown_h = height - 0.55 * (height - 2.0)
        trunk_r = 0.015 * height + 0.08 if form == "broadleaf" else 0.012 * height + 0.06
        v, f = frustums(np.stack([zero, zero, zero - 0.5], -1), np.stack([zero, zero, crown_h], -1),
                        trunk_r, trunk_r * 0.7, 6, top=False)
        add(v, f, *_BARK, 0.05)
        if form == "broadleaf":
            off = rng.uniform([-0.35, -0.35, -0.3], [0.35, 0.35, 0.3], (n, n_lumps, 3)) * \
                np.stack([rc, rc, half_z], -1)[:, None]
            lump_c = np.stack([zero, zero, crown_h], -1)[:, None] + off
            lump_r = rng.uniform(0.6, 0.78, (n, n_lumps, 1)) * np.stack([rc, rc, half_z], -1)[:, None]
        else:  # poplar: a tall narrow ellipsoid from ~2.5 m to the top, in two overlapping lumps
            start = rng.uniform(1.5, 3.0, n)
            half = (height - start) / 2
            k = np.array([0.42, 0.62])
            lump_c = np.stack([np.repeat(zero[:, None], 2, 1) + rng.uniform(-0.15, 0.15, (n, 2)) * rc[:, None],
                               np.repeat(zero[:, None], 2, 1) + rng.uniform(-0.15, 0.15, (n, 2)) * rc[:, None],
                               start[:, None] + k * 2 * half[:, None]], -1)
            lump_r = np.stack([rc[:, None] * [1.0, 0.8], rc[:, None] * [1.0, 0.8],
                               half[:, None] * [0.85, 0.7]], -1)
    tint = rng.uniform(0.8, 1.15, (n, 1, 1))
    for k in range(lump_c.shape[1]):
        v, f = blobs(rng, lump_c[:, k], lump_r[:, k], 1, 0.16)
        alb = albedo_draw(rng, base, spread, n, len(f), 0.07) * tint
        out.append(Batch(ground.place(v, x, yl), f, alb, "tree"))
    return out


def bush_batches(ground: Ground, lay: Layout, rng: np.random.Generator, look: RoadsideLook,
            right_min_d: float) -> list[Batch]:
    x, side = _both_sides(rng, lay, look.bush_density, 2.5, 4.0)
    n = len(x)
    if n == 0:
        return []
    r = rng.uniform(0.5, 1.5, n)
    d = np.maximum(rng.uniform(1.0, look.tree_setback_m + 25.0, n), 1.5 * r + 0.4)
    d = np.where(side < 0, np.maximum(d, right_min_d + 1.5 * r), d)
    keep = d + 1.5 * r <= lay.max_offset
    x, side, d, r = x[keep], side[keep], d[keep], r[keep]
    n = len(x)
    yl = lay.yl(side, d)
    out = []
    for k in range(2):
        off = r[:, None] * rng.uniform([-0.45, -0.3, 0.0], [0.45, 0.3, 0.2], (n, 3))
        c = off + np.stack([np.zeros(n), np.zeros(n), 0.45 * r], -1)
        rad = r[:, None] * rng.uniform(0.7, 1.0, (n, 1)) * [1.0, 1.0, 0.75]
        v, f = blobs(rng, c, rad, 0, 0.18)
        out.append(Batch(ground.place(v, x, yl), f, albedo_draw(rng, (60, 82, 38), (14, 16, 10), n, len(f), 0.08),
                          "bush"))
    return out


def pole_batches(ground: Ground, lay: Layout, rng: np.random.Generator, spacing: float) -> list[Batch]:
    """Lighting poles every ``spacing`` m on one or both verges, each arm reaching towards the road."""
    if spacing <= 0:
        return []
    which = rng.choice(["right", "left", "both"])
    height, arm, d_pole = rng.uniform(9, 12), rng.uniform(1.5, 2.2), 0.65 + 2.2
    xs, sides = [], []
    phase = rng.uniform(0, spacing)
    for side, name in ((-1, "right"), (+1, "left")):
        if which in (name, "both"):
            x = np.arange(lay.x0 + phase + (spacing / 2 if name == "left" and which == "both" else 0), lay.x1, spacing)
            xs.append(x)
            sides.append(np.full(len(x), side))
    x, side = np.concatenate(xs), np.concatenate(sides)
    n = len(x)
    yl = lay.yl(side, np.full(n, d_pole))
    zero, one = np.zeros(n), np.ones(n)
    towards = -side.astype(float)          # +b is left: the road lies at -b on the left verge
    grey = (150, 152, 155), (10, 10, 10)
    out = []
    v, f = frustums(np.stack([zero, zero, zero - 0.3], -1), np.stack([zero, zero, zero + height], -1),
                    one * 0.12, one * 0.07, 8)
    out.append(Batch(ground.place(v, x, yl), f, albedo_draw(rng, *grey, n, len(f)), "pole"))
    v, f = boxes(np.stack([zero, towards * arm / 2, zero + height - 0.15], -1), np.tile([[0.08, arm, 0.08]], (n, 1)),
                 bottom=True)
    out.append(Batch(ground.place(v, x, yl), f, albedo_draw(rng, *grey, n, len(f)), "pole"))
    v, f = boxes(np.stack([zero, towards * (arm - 0.3), zero + height - 0.25], -1),
                 np.tile([[0.3, 0.6, 0.14]], (n, 1)), bottom=True)
    out.append(Batch(ground.place(v, x, yl), f, albedo_draw(rng, (95, 97, 100), (8, 8, 8), n, len(f)), "pole"))
    return out


_SIGN_COLOURS = np.array([[28, 72, 150], [24, 105, 62], [235, 235, 230], [230, 190, 40]], float)


def plate_faces(rng, n: int, f: np.ndarray, verts: np.ndarray, front: np.ndarray) -> np.ndarray:
    """Albedo of thin plates: the face whose normal points along -a (towards oncoming traffic) in
    the plate colour ``front`` (n, 3), the rest galvanised grey."""
    t = verts[0][f]
    normal = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    is_front = normal[:, 0] < -0.5 * np.linalg.norm(normal, axis=1)
    alb = albedo_draw(rng, (150, 150, 150), (10, 10, 10), n, len(f))
    alb[:, is_front] = front[:, None, :]
    return alb


def sign_batches(ground: Ground, lay: Layout, rng: np.random.Generator, density: float,
           right_min_d: float) -> list[Batch]:
    """Signs facing oncoming traffic: large direction boards on two posts, small plates on one."""
    xs, sides = [], []
    for side in (+1, -1):
        x = _xs_along(rng, lay, density * (1.0 if side < 0 else 0.4), 1.0, 0.0)
        xs.append(x)
        sides.append(np.full(len(x), side))
    x, side = np.concatenate(xs), np.concatenate(sides)
    if len(x) == 0:
        return []
    big = rng.uniform(size=len(x)) < 0.6
    out = []
    for sel, is_big in ((big, True), (~big, False)):
        xb, sb = x[sel], side[sel]
        n = len(xb)
        if n == 0:
            continue
        zero = np.zeros(n)
        w = rng.uniform(2.5, 4.5, n) if is_big else np.full(n, 0.8)
        h = rng.uniform(1.5, 2.5, n) if is_big else np.full(n, 0.8)
        bottom = rng.uniform(1.6, 2.2, n)
        near = np.maximum(0.8, right_min_d + 0.3) * (sb < 0) + 0.9 * (sb > 0)
        yl = lay.yl(sb, near + w / 2)                  # the plate's centre: its road-side edge `near` out
        colour = _SIGN_COLOURS[rng.integers(0, 2, n)] if is_big else _SIGN_COLOURS[rng.integers(0, 4, n)]
        v, f = boxes(np.stack([zero, zero, bottom + h / 2], -1), np.stack([zero + 0.06, w, h], -1), bottom=True)
        out.append(Batch(ground.place(v, xb, yl), f, plate_faces(rng, n, f, v, colour), "sign"))
        offsets = (-(w / 2 - 0.35), w / 2 - 0.35) if is_big else (zero,)
        for off in offsets:
            v, f = boxes(np.stack([zero + 0.1, off, (bottom + h - 0.1 - 0.4) / 2], -1),
                         np.stack([zero + 0.1, zero + 0.1, bottom + h - 0.1 + 0.4], -1))
            out.append(Batch(ground.place(v, xb, yl), f, albedo_draw(rng, (140, 142, 145), (8, 8, 8), n, len(f)),
                              "sign"))
    return out


def gantry_batches(ground: Ground, lay: Layout, rng: np.random.Generator, spacing: float, n_lanes: int,
              lane_width: float) -> list[Batch]:
    """Gantries every ``spacing`` m: legs 1.5 m beyond the band, a beam 6.2-7.4 m up carrying
    direction plates (bottoms >= 5.7 m) over the lanes, facing oncoming traffic."""
    if spacing <= 0:
        return []
    x = np.arange(lay.x0 + rng.uniform(0.2, 0.8) * spacing, lay.x1, spacing)
    n = len(x)
    if n == 0:
        return []
    zero = np.zeros(n)
    yl_l, yl_r = lay.edge_left + 1.5, lay.edge_right - 1.5
    out = []
    grey = (140, 142, 146), (10, 10, 10)
    for yl_leg in (yl_l, yl_r):
        v, f = boxes(np.stack([zero, zero + yl_leg, zero + 3.6], -1), np.tile([[0.45, 0.45, 8.2]], (n, 1)))
        out.append(Batch(ground.place(v, x, zero), f, albedo_draw(rng, *grey, n, len(f)), "gantry"))
    v, f = boxes(np.stack([zero, zero + (yl_l + yl_r) / 2, zero + 6.8], -1),
                 np.tile([[0.8, yl_l - yl_r + 0.45, 1.2]], (n, 1)), bottom=True)
    out.append(Batch(ground.place(v, x, zero), f, albedo_draw(rng, *grey, n, len(f)), "gantry"))
    n_plates = max(1, min(3, n_lanes - 1))
    for k in range(n_plates):
        lane = (k + 0.5) * n_lanes / n_plates - 0.5
        width = min(4.2, 0.9 * n_lanes * lane_width / n_plates)
        v, f = boxes(np.stack([zero - 0.45, zero - lane * lane_width, zero + 5.7 + 1.0], -1),
                     np.tile([[0.06, width, 2.0]], (n, 1)), bottom=True)
        colour = _SIGN_COLOURS[rng.integers(0, 2, n)]
        out.append(Batch(ground.place(v, x, zero), f, plate_faces(rng, n, f, v, colour), "gantry"))
    return out


# --------------------------------------------------------------------------- far: buildings and hills
def _centre_line(ground: Ground, road: Road, lay: Layout, step: float = 20.0) -> tuple[np.ndarray, np.ndarray]:
    """Road x and W points (N, 3) of the carriageway's middle, ``step`` m apart."""
    x = np.linspace(lay.x0, lay.x1, int(math.ceil((lay.x1 - lay.x0) / step)) + 1)
    mid = -(road.lanes - 1) / 2 * road.lane_width_m
    return x, ground.bend(x, mid, 0.0)


_WALLS = np.array([[226, 220, 205], [200, 190, 170], [160, 92, 70], [178, 178, 172], [215, 205, 180]], float)
_ROOFS = np.array([[150, 60, 45], [110, 55, 45], [80, 80, 85], [120, 110, 100]], float)


def building_batches(ground: Ground, road: Road, lay: Layout, rng: np.random.Generator, density: float) -> list[Batch]:
    """Houses and sheds in hamlets 150-800 m from the road: boxes with gable roofs."""
    cx, line = _centre_line(ground, road, lay)
    half_road = (lay.edge_left - lay.edge_right) / 2
    xs, sides = [], []
    for side in (+1, -1):
        x = _xs_along(rng, lay, density, 4.0, 40.0)
        xs.append(x)
        sides.append(np.full(len(x), side))
    x, side = np.concatenate(xs), np.concatenate(sides)
    x = x[:MAX_BUILDINGS]
    side = side[: len(x)]
    n = len(x)
    if n == 0:
        return []
    d = 150 + 650 * rng.uniform(0, 1, n) ** 1.5 + rng.normal(0, 20, n)
    d = np.clip(d, 150, 800)
    mid = -(road.lanes - 1) / 2 * road.lane_width_m
    pos = ground.bend(x, mid + side * (half_road + d), 0.0)
    dist = np.min(np.linalg.norm(pos[:, None, :2] - line[None, :, :2], axis=-1), axis=1)
    keep = dist >= 150 + half_road - 10                        # a curve brings no building closer
    near = np.argmin(np.linalg.norm(pos[:, None, :2] - line[None, :, :2], axis=-1), axis=1)
    pos[:, 2] = ground.z(cx[near])
    pos, n = pos[keep], int(keep.sum())
    if n == 0:
        return []
    shed = rng.uniform(size=n) < 0.25
    length = np.where(shed, rng.uniform(25, 60, n), rng.uniform(8, 18, n))
    width = np.where(shed, rng.uniform(12, 25, n), rng.uniform(7, 11, n))
    walls = np.where(shed, rng.uniform(5, 8, n), rng.uniform(3, 7, n))
    roof = np.where(shed, rng.uniform(0.8, 1.5, n), rng.uniform(2.0, 4.0, n))
    yaw = rng.uniform(0, np.pi, n)
    zero = np.zeros(n)
    bv, bf = boxes(np.stack([zero, zero, (walls - 2.0) / 2], -1), np.stack([length, width, walls + 2.0], -1))
    # Gable roof: ridge along a, eaves at the wall tops.
    a, b = length / 2, width / 2
    top = walls + roof
    rv = np.stack([np.stack(c, -1) for c in ((-a, -b, walls), (a, -b, walls), (a, zero, top), (-a, zero, top),
                                             (-a, b, walls), (a, b, walls))], 1)
    rf = np.array([[0, 1, 2], [0, 2, 3], [5, 4, 3], [5, 3, 2], [1, 5, 2], [4, 0, 3]])

    def turn(v):
        c, s = np.cos(yaw)[:, None], np.sin(yaw)[:, None]
        return np.stack([c * v[..., 0] - s * v[..., 1] + pos[:, None, 0],
                         s * v[..., 0] + c * v[..., 1] + pos[:, None, 1], v[..., 2] + pos[:, None, 2]], -1)

    wall_c = _WALLS[rng.integers(0, len(_WALLS), n)]
    roof_c = _ROOFS[rng.integers(0, len(_ROOFS), n)]
    wall_alb = np.repeat(wall_c[:, None], len(bf), 1) * rng.uniform(0.9, 1.1, (n, 1, 1))
    roof_alb = np.repeat(roof_c[:, None], len(rf), 1) * rng.uniform(0.9, 1.1, (n, 1, 1))
    return [Batch(turn(bv), bf, wall_alb, "building"), Batch(turn(rv), rf, roof_alb, "building")]


def hill_batches(ground: Ground, road: Road, lay: Layout, rng: np.random.Generator, height: float,
           n_azimuth: int = 360) -> list[Batch]:
    """A ring of hills around the road: its inner slope rises from 3 m under the ground at half the
    ridge distance to a ridge of ``height`` m (smooth, random along the ring) at distance D from
    the road, D = clip(5500 m - length - 300 m, 2000, 3500)."""
    if height < 1.0:
        return []
    cx, line = _centre_line(ground, road, lay)
    ridge_d = float(np.clip(HILL_MAX_DISTANCE_M - (lay.x1 - MARGIN_M), 2000.0, 3500.0))
    centre = line[len(line) // 2, :2]
    phi = 2 * np.pi * np.arange(n_azimuth) / n_azimuth
    u = np.stack([np.cos(phi), np.sin(phi)], -1)
    w = line[:, :2] - centre
    proj = u @ w.T                                                     # (A, N)
    perp2 = np.sum(w * w, axis=1)[None] - proj ** 2

    def radius(dist: float) -> np.ndarray:
        """Distance from the centre along each azimuth to the first point >= ``dist`` from every sample."""
        reach = proj + np.sqrt(np.clip(dist ** 2 - perp2, 0, None))
        return np.max(np.where(perp2 < dist ** 2, reach, 0.0), axis=1)

    def ridge_noise(amplitudes_decay: float) -> np.ndarray:
        k = np.arange(1, 13)
        amp = rng.uniform(0.5, 1.0, len(k)) / k ** amplitudes_decay
        ph = rng.uniform(0, 2 * np.pi, len(k))
        s = np.sum(amp[:, None] * np.cos(k[:, None] * phi[None] + ph[:, None]), axis=0)
        return (s - s.min()) / (s.max() - s.min())

    shape = np.array([0.0, 0.18, 0.55, 0.85, 1.0])
    fractions = np.array([0.45, 0.62, 0.78, 0.9, 1.0])
    crest = height * (0.25 + 0.75 * ridge_noise(1.2))
    rows = []
    for frac, sh in zip(fractions, shape):
        r = radius(frac * ridge_d)
        xy = centre + r[:, None] * u
        near = np.argmin(np.linalg.norm(xy[:, None] - line[None, :, :2], axis=-1), axis=1)
        z = ground.z(cx[near]) + (sh * crest * (0.8 + 0.4 * ridge_noise(1.0)) if sh > 0 else -3.0)
        rows.append(np.concatenate([xy, z[:, None]], axis=1))
    rows = np.stack(rows)                                              # (R, A, 3)
    i, j = np.arange(n_azimuth), (np.arange(n_azimuth) + 1) % n_azimuth
    verts = np.concatenate([rows[:-1], rows[1:]], axis=1)              # (R-1, 2A, 3): inner then outer row
    a = n_azimuth
    faces = np.concatenate([np.stack([i, j, a + j], -1), np.stack([i, a + j, a + i], -1)])
    t = verts[:, faces]
    up = np.cross(t[..., 1, :] - t[..., 0, :], t[..., 2, :] - t[..., 0, :])[..., 2]
    if np.mean(up) < 0:                                                # face up and inwards (towards the road)
        faces = faces[:, ::-1]
    green = albedo_draw(rng, (88, 112, 78), (10, 10, 8), 1, 1)[0, 0]
    blue = np.array([120.0, 135.0, 140.0])
    mix = np.linspace(0.2, 0.75, len(rows) - 1)[:, None, None]
    alb = (1 - mix) * green + mix * blue
    alb = np.broadcast_to(alb, (len(rows) - 1, len(faces), 3)) * (1 + rng.uniform(-0.05, 0.05, (len(rows) - 1,
                                                                                               len(faces), 1)))
    return [Batch(verts, faces, alb, "hill")]


# --------------------------------------------------------------------------- shadows
def ground_shadows(parts: list[np.ndarray], sun_w: np.ndarray, ground: Ground | None = None,
                   max_edge_m: float = 8.0) -> np.ndarray:
    """(S, 3, 3) W triangles (counter-clockwise from above) of the shadows ``parts`` (a list of
    (V_i, 3) W point sets, one convex piece each) cast on the ground for light travelling along
    the unit ``sun_w``: each point (no lower than the ground under it) moved along ``sun_w`` to
    the ground, the 2-D convex hull of each part's points fanned, cut to edges <= ``max_edge_m``
    on a vertical profile, and lifted ``3 cm - 1 cm * i / n`` above the ground (part i of n).

    On a profile each ray meets the ground by Newton iterations on its height above ``z(x(t))``
    (``x(t)``: the road x under the ray point, :meth:`Ground.road_frame`), and the polygons'
    vertices are lifted with their own ground height."""
    ground = ground or Ground()
    s = np.asarray(sun_w, dtype=float)
    s = s / np.linalg.norm(s)
    if -s[2] < math.sin(math.radians(MIN_SUN_ELEVATION_DEG)) or not parts:
        return np.zeros((0, 3, 3))
    counts = np.array([len(p) for p in parts])
    pts = np.concatenate(parts).astype(float)
    n = len(parts)
    starts = np.r_[0, np.cumsum(counts)]
    centre = np.add.reduceat(pts, starts[:-1], axis=0) / counts[:, None]
    if ground.profile is None:                       # flat ground at Z = 0
        t = np.maximum(pts[:, 2], 0.0) / -s[2]
    else:   # Newton on the ray's height above the ground z(x(t)), x from the part's centre on
        xc, gx, gy = ground.road_frame(centre[:, :2])
        rel = pts[:, :2] - np.repeat(centre[:, :2], counts, axis=0)
        x = np.repeat(xc, counts) + rel[:, 0] * np.repeat(gx, counts) + rel[:, 1] * np.repeat(gy, counts)
        x, gx, gy = ground.road_frame(pts[:, :2], x)
        zg, slope = ground.z_slope(x)
        z0 = np.maximum(pts[:, 2], zg)
        t = (z0 - zg) / (slope * (s[0] * gx + s[1] * gy) - s[2])     # exact on a uniform grade
        for _ in range(3):
            x, gx, gy = ground.road_frame(pts[:, :2] + t[:, None] * s[:2], x, steps=1)
            zg, slope = ground.z_slope(x)
            t = t - (z0 + t * s[2] - zg) / (s[2] - slope * (s[0] * gx + s[1] * gy))
    q = pts[:, :2] + t[:, None] * s[:2]
    middle = np.add.reduceat(q, starts[:-1], axis=0) / counts[:, None]
    rel = (q - np.repeat(middle, counts, axis=0)).astype(np.float32)
    hulls = [cv2.convexHull(rel[a:b], returnPoints=False).ravel() + a for a, b in zip(starts[:-1], starts[1:])]
    k = np.array([len(h) for h in hulls])
    fans = np.maximum(k - 2, 0)
    if fans.sum() == 0:
        return np.zeros((0, 3, 3))
    idx = np.concatenate(hulls)
    first = np.r_[0, np.cumsum(k)[:-1]]
    part = np.repeat(np.arange(n), fans)
    j = np.arange(fans.sum()) - np.repeat(np.r_[0, np.cumsum(fans)[:-1]], fans) + 1
    o = first[part]
    t2d = q[np.stack([idx[o], idx[o + j], idx[o + j + 1]], axis=1)]            # (T, 3, 2)
    e1, e2 = t2d[:, 1] - t2d[:, 0], t2d[:, 2] - t2d[:, 0]
    area = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    ok = np.abs(area) > 1e-10
    t2d, area, part = t2d[ok], area[ok], part[ok]
    t2d = np.where((area < 0)[:, None, None], t2d[:, ::-1], t2d)              # counter-clockwise from above
    lift = SHADOW_LIFT_M[1] - (SHADOW_LIFT_M[1] - SHADOW_LIFT_M[0]) * part / n
    if ground.profile is not None:
        t2d, lift, xv = _subdivide(ground, t2d, lift, xc[part], max_edge_m)
        z = ground.z_slope(xv)[0]
    else:
        z = np.zeros(t2d.shape[:2])
    order = np.argsort(-lift, kind="stable")                                # highest first: draw order
    return np.concatenate([t2d, (z + lift[:, None])[..., None]], axis=-1)[order]


def _subdivide(ground: Ground, tris: np.ndarray, lift: np.ndarray, x_near: np.ndarray,
               max_edge: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """2-D triangles (T, 3, 2) split into four at their edge midpoints while an edge is longer
    than ``max_edge`` over a vertical curve (or, with a plan, where road x is not linear in W,
    2.5 ``max_edge`` anywhere): the ground is then flat within ~1 cm under each. Returns the
    triangles, their lifts and the road x of their vertices (``x_near``: road x near each)."""
    prof = ground.profile
    curves = [(a, a + n) for a, n in zip(prof.starts, prof.lengths) if n > 0]
    longest = 2.5 * max_edge if ground.plan is not None else math.inf
    xv = ground.road_frame(tris.reshape(-1, 2), np.repeat(x_near, 3), steps=3)[0].reshape(-1, 3)
    out_t, out_l, out_x = [], [], []
    for _ in range(12):
        e = np.linalg.norm(tris - np.roll(tris, -1, axis=1), axis=-1).max(axis=1)
        lo, hi = xv.min(axis=1), xv.max(axis=1)
        curved = np.zeros(len(tris), dtype=bool)
        for a, b in curves:
            curved |= (lo < b) & (hi > a)
        big = (curved & (e > max_edge)) | (e > longest)
        out_t.append(tris[~big])
        out_l.append(lift[~big])
        out_x.append(xv[~big])
        if not big.any():
            break
        t, x = tris[big], xv[big]
        mids = (t + np.roll(t, -1, axis=1)) / 2                          # ab, bc, ca
        xm = ground.road_frame(mids.reshape(-1, 2), ((x + np.roll(x, -1, axis=1)) / 2).ravel())[0].reshape(-1, 3)
        a, b, c = t[:, 0], t[:, 1], t[:, 2]
        ab, bc, ca = mids[:, 0], mids[:, 1], mids[:, 2]
        xa, xb, xc = x[:, 0], x[:, 1], x[:, 2]
        xab, xbc, xca = xm[:, 0], xm[:, 1], xm[:, 2]
        tris = np.concatenate([np.stack(v, 1) for v in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])
        xv = np.concatenate([np.stack(v, 1) for v in ((xa, xab, xca), (xab, xb, xbc), (xca, xbc, xc),
                                                      (xab, xbc, xca))])
        lift = np.tile(lift[big], 4)
    return np.concatenate(out_t), np.concatenate(out_l), np.concatenate(out_x)
