"""Low-poly car-like vehicle meshes and their colours.

Model frame (see :mod:`harness.world.geometry`): X forward, Y left, Z up, origin
on the ground at the footprint centre. Every mesh fills its length x width
footprint exactly: the rear bumper is at X = -length/2 (so ``d_long`` measures
the distance to it), the body sides at Y = +-width/2, and it rises from the
ground (tyre contact) to :func:`harness.world.vehicles.vehicle_height`. Cars keep real proportions:
rear overhang 0.8-1.1 m behind the rear axle, ground clearance 0.17 m, wheel
radius 0.32 m. Vehicles longer than 7 m are trucks with box bodies. The dimensions are the world's
(:mod:`harness.world.vehicles`); this module makes meshes and colours of them.

The wheel polygons (``WHEEL_SECTIONS`` sides) have a vertex straight down, so
the tyres touch the ground along the line X = axle, Z = 0.

The realistic look draws detailed vehicles instead (:func:`vehicle_faces_detailed`: lamps, plates,
windows between pillars, arches, rims, grime, the dark ground under the body; per-face
:class:`~harness.render.materials.Material` tags). They fill the same footprint box exactly (the
mirrors are the widest part, the body is inset for them); the simple meshes are unchanged.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import trimesh
from scipy.spatial import ConvexHull

from harness.render.materials import Material
from harness.world.vehicles import vehicle_layout

WHEEL_SECTIONS = 12

# Common car paints (RGB 0..255).
PALETTE = np.array([
    [235, 235, 232], [25, 25, 28], [160, 163, 168], [95, 98, 104], [170, 25, 30],
    [25, 55, 130], [20, 30, 60], [30, 80, 50], [200, 185, 150], [225, 180, 30],
    [210, 90, 20], [110, 20, 35], [70, 130, 180], [140, 120, 100],
], dtype=float)
GLASS = (30, 38, 48)
TYRE = (22, 22, 22)
RIM = (120, 120, 125)
TAIL_LIGHT = (150, 10, 10)
TRIM = (40, 40, 42)


def vehicle_color(palette_seed: int, vehicle_id: int) -> tuple[int, int, int]:
    """Deterministic paint colour (RGB 0..255) of a vehicle."""
    rng = np.random.default_rng([int(palette_seed) & 0xFFFFFFFF, int(vehicle_id) & 0xFFFFFFFF])
    base = PALETTE[rng.integers(len(PALETTE))]
    rgb = np.clip(base * rng.uniform(0.9, 1.1) + rng.normal(0.0, 6.0, 3), 0, 255)
    return tuple(int(c) for c in np.round(rgb))


def _paint(m: trimesh.Trimesh, color) -> trimesh.Trimesh:
    """Face colours ``color``; None marks the part as painted in the vehicle's colour (left for later)."""
    if color is None:
        m.metadata["painted"] = True
    else:
        m.visual.face_colors = (*color, 255)
    return m


def _box(x0, x1, y0, y1, z0, z1, color) -> trimesh.Trimesh:
    m = trimesh.creation.box(extents=(x1 - x0, y1 - y0, z1 - z0))
    m.apply_translation(((x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2))
    return _paint(m, color)


def _hull(points, color) -> trimesh.Trimesh:
    return _paint(trimesh.convex.convex_hull(np.asarray(points, dtype=float)), color)


def _wheel(x: float, y_outer: float, side: int, radius: float, width: float) -> trimesh.Trimesh:
    """A tyre: a prism with its axis along Y and a vertex straight down."""
    ang = -np.pi / 2 + np.arange(WHEEL_SECTIONS) * 2 * np.pi / WHEEL_SECTIONS
    ring = np.stack([x + radius * np.cos(ang), radius + radius * np.sin(ang)], axis=-1)
    y_in = y_outer - width
    pts = [(px, side * yy, pz) for yy in (y_in, y_outer) for px, pz in ring]
    m = _hull(pts, TYRE)
    return m


def vehicle_trimesh(length: float, width: float, color: tuple[int, int, int],
                    body: str | None = None) -> trimesh.Trimesh:
    """One merged mesh (face colours) of a vehicle in its model frame."""
    return trimesh.util.concatenate(_vehicle_parts(length, width, color, body))


def vehicle_faces(length: float, width: float, color: tuple[int, int, int], detailed: bool = False,
                  dirt: float = 0.0, seed: int = 0,
                  body: str | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`vehicle_trimesh`'s triangles (F, 3, 3), face normals (F, 3) and face colours (F, 3) (0..255, float),
    the shape built once per footprint (the convex hulls are the cost) and painted per call.

    ``detailed``: the realistic look's vehicle instead (:func:`vehicle_faces_detailed` without its material
    tags; ``dirt`` and ``seed`` as there). Without it ``dirt`` and ``seed`` are ignored. ``body``: a body type of
    :mod:`harness.world.vehicles` (None: the footprint decides); the simple mesh takes the layout's heights."""
    if detailed:
        return vehicle_faces_detailed(length, width, color, dirt, seed, body)[:3]
    triangles, normals, colors, painted = _vehicle_shape(length, width, body)
    colors = colors.copy()
    colors[painted] = color
    return triangles, normals, colors


@functools.lru_cache(maxsize=256)
def _vehicle_shape(length: float, width: float,
                   body: str | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Read-only triangles, face normals, face colours (painted faces unset) and painted-face mask of one footprint."""
    parts = _vehicle_parts(length, width, None, body)
    tm = trimesh.util.concatenate(parts)
    painted = np.repeat([bool(p.metadata.get("painted")) for p in parts], [len(p.faces) for p in parts])
    out = (tm.vertices[tm.faces], tm.face_normals, tm.visual.face_colors[:, :3].astype(float), painted)
    for a in out:
        a.setflags(write=False)
    return out


def _vehicle_parts(length: float, width: float, color: tuple[int, int, int] | None,
                   body: str | None = None) -> list[trimesh.Trimesh]:
    """The parts of :func:`vehicle_trimesh`; ``color`` None leaves the painted ones uncoloured (marked ``painted``)."""
    L = vehicle_layout(length, width, body)
    hl, hw = length / 2, width / 2
    parts: list[trimesh.Trimesh] = []
    if L.truck:
        cab_len = 2.4
        parts.append(_box(-hl, hl, -hw + 0.05, hw - 0.05, L.clearance, L.belt, TRIM))            # chassis
        parts.append(_box(-hl, hl - cab_len - 0.1, -hw, hw, L.belt, L.roof, color))             # cargo box
        parts.append(_box(hl - cab_len, hl, -hw, hw, L.belt, 2.2, color))                         # cab lower
        parts.append(_hull([(hl - cab_len, -hw + 0.05, 2.2), (hl - cab_len, hw - 0.05, 2.2),
                            (hl - 0.1, -hw + 0.05, 2.2), (hl - 0.1, hw - 0.05, 2.2),
                            (hl - cab_len, -hw + 0.1, 3.0), (hl - cab_len, hw - 0.1, 3.0),
                            (hl - 0.4, -hw + 0.1, 3.0), (hl - 0.4, hw - 0.1, 3.0)], GLASS))       # cab glass
        parts.append(_box(-hl, -hl + 0.04, -hw + 0.1, -hw + 0.35, 0.6, 0.9, TAIL_LIGHT))
        parts.append(_box(-hl, -hl + 0.04, hw - 0.35, hw - 0.1, 0.6, 0.9, TAIL_LIGHT))
        axles = list(L.axles)
    else:
        lower_top = 0.6
        parts.append(_box(-hl, hl, -hw, hw, L.clearance, lower_top, color))                       # bumpers + sills
        parts.append(_box(-hl + 0.04, hl - 0.05, -hw, hw, lower_top, L.belt, color))              # upper body
        parts.append(_box(-hl, -hl + 0.04, -hw + 0.08, -hw + 0.38, 0.66, 0.85, TAIL_LIGHT))       # tail lights
        parts.append(_box(-hl, -hl + 0.04, hw - 0.38, hw - 0.08, 0.66, 0.85, TAIL_LIGHT))
        parts.append(_box(-hl, -hl + 0.04, -0.26, 0.26, 0.38, 0.5, TRIM))                          # plate recess
        tall = L.roof > 1.8
        rear_b, front_b = (-hl + 0.25, hl - 1.0) if tall else (-hl + 0.7, hl - 1.5)
        rear_t, front_t = (-hl + 0.35, hl - 1.3) if tall else (-hl + 1.2, hl - 2.2)
        top = L.roof - 0.06
        parts.append(_hull([(rear_b, -hw + 0.06, L.belt), (rear_b, hw - 0.06, L.belt),
                            (front_b, -hw + 0.06, L.belt), (front_b, hw - 0.06, L.belt),
                            (rear_t, -hw + 0.2, top), (rear_t, hw - 0.2, top),
                            (front_t, -hw + 0.2, top), (front_t, hw - 0.2, top)], GLASS))        # greenhouse
        parts.append(_box(rear_t, front_t, -hw + 0.2, hw - 0.2, top, L.roof, color))              # roof
        axles = [L.rear_axle_x, L.front_axle_x]
    for ax in axles:
        for side in (-1, 1):
            parts.append(_wheel(ax, L.wheel_y, side, L.wheel_radius, L.wheel_width))
    return parts


# ------------------------------------------------------------------ detailed vehicles (the realistic look)
# Built from explicit triangles (no merging): convex hulls for rounded parts, lofts of plan rings for the
# body, quads laid 6-40 mm proud of a surface for lamps, plates, arches and gaps (clear of depth-buffer
# fighting to ~80 m). Every part carries a :class:`~harness.render.materials.Material` tag and a colour:
# a fixed sRGB, the vehicle's paint, or the paint under road grime.

MUD = (96, 80, 58)
TRIM_BLACK = (38, 38, 40)
RECESS = (14, 14, 15)
GAP = (20, 20, 21)
GLASS_TINT = (26, 32, 40)
SHADOW_OUTER = (58, 58, 58)
SHADOW_INNER = (30, 30, 30)
PLATE_WHITE = (232, 232, 226)
PLATE_YELLOW = (238, 196, 40)
PLATE_BLUE = (30, 60, 160)
LAMP_TAIL = (150, 8, 10)
LAMP_BRAKE = (200, 24, 24)
LAMP_AMBER = (225, 125, 25)
LAMP_WHITE = (215, 215, 210)
LAMP_HEAD = (205, 210, 216)
RIMS = ((176, 179, 183), (88, 90, 95), (150, 150, 152))
TRUCK_BOXES = ((242, 242, 238), (205, 207, 210), None)     # white, light grey, the paint
DETAILED_SECTIONS = 16
CAR_MAX_TRIANGLES = 2500
TRUCK_MAX_TRIANGLES = 4000
_PAINT = "paint"
PAINT_MAT, GLASS_MAT, TYRE_MAT, RIM_MAT = Material.PAINT, Material.GLASS, Material.TYRE, Material.RIM
LIGHT_MAT, PLATE_MAT, TRIM_MAT, DIRT_MAT, SHADOW_MAT = (Material.LIGHT, Material.PLATE, Material.TRIM,
                                                        Material.DIRT, Material.SHADOW)
# Seven-segment strokes of a plate character: (x0, x1, z0, z1) in a unit cell.
_SEGMENTS = ((0.1, 0.9, 0.88, 1.0), (0.78, 0.9, 0.5, 0.95), (0.78, 0.9, 0.05, 0.5), (0.1, 0.9, 0.0, 0.12),
             (0.1, 0.22, 0.05, 0.5), (0.1, 0.22, 0.5, 0.95), (0.1, 0.9, 0.44, 0.56))
_DIGITS = (0b0111111, 0b0000110, 0b1011011, 0b1001111, 0b1100110, 0b1101101, 0b1111101, 0b0000111,
           0b1111111, 0b1101111, 0b1110111, 0b1111100, 0b0111001, 0b1011110, 0b1111001, 0b1110001)


class _Parts:
    """Triangles with, per face, a colour (fixed sRGB, paint, or paint with grime of a strength) and a material."""

    def __init__(self) -> None:
        self.tris: list[np.ndarray] = []
        # per part: fixed sRGB, role (0 fixed, 1 paint, 2 paint under grime), grime strength, material
        self.meta: list[tuple] = []

    def add(self, tris: np.ndarray, colour, material, grime: float = 0.0) -> None:
        tris = np.asarray(tris, dtype=float).reshape(-1, 3, 3)
        painted = isinstance(colour, str)
        if painted:
            self.meta.append(((0.0, 0.0, 0.0), 2 if grime > 0 else 1, grime, int(material)))
        else:
            if grime > 0:
                colour = tuple((1 - grime) * np.asarray(colour, float) + grime * np.asarray(MUD, float))
            self.meta.append((tuple(float(c) for c in colour), 0, 0.0, int(material)))
        self.tris.append(tris)

    def arrays(self):
        tris = np.concatenate(self.tris)
        counts = [len(t) for t in self.tris]
        cross = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
        normals = cross / np.linalg.norm(cross, axis=1, keepdims=True)
        fixed, role, grime, material = zip(*self.meta)
        return (tris, normals, np.repeat(np.array(fixed), counts, axis=0), np.repeat(np.array(role, np.int8), counts),
                np.repeat(np.array(grime), counts), np.repeat(np.array(material, np.int8), counts))


def _facing(tris: np.ndarray, direction) -> np.ndarray:
    """``tris`` (n, 3, 3) with each triangle's winding turned so its normal has a positive part along ``direction``."""
    tris = np.asarray(tris, dtype=float).reshape(-1, 3, 3)
    d = np.asarray(direction, dtype=float)
    if d.ndim == 1:
        d = np.broadcast_to(d, (len(tris), 3))
    flip = np.einsum("ij,ij->i", np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), d) < 0
    tris[flip] = tris[flip][:, [0, 2, 1]]
    return tris


def _outward(tris: np.ndarray, centre) -> np.ndarray:
    """Triangles of a convex part wound to face away from ``centre``."""
    tris = np.asarray(tris, dtype=float).reshape(-1, 3, 3)
    return _facing(tris, tris.mean(axis=1) - np.asarray(centre, float))


def _fan(points, direction) -> np.ndarray:
    """A convex planar polygon (N, 3) -> N - 2 triangles facing ``direction``."""
    p = np.asarray(points, dtype=float)
    (ax, ay, az), (bx, by, bz), (cx, cy, cz) = p[0].tolist(), p[1].tolist(), p[-1].tolist()
    ux, uy, uz, vx, vy, vz = bx - ax, by - ay, bz - az, cx - ax, cy - ay, cz - az
    dx, dy, dz = (float(v) for v in direction)
    if (uy * vz - uz * vy) * dx + (uz * vx - ux * vz) * dy + (ux * vy - uy * vx) * dz < 0:
        p = p[::-1]
    k = len(p) - 2
    tris = np.empty((k, 3, 3))
    tris[:, 0] = p[0]
    tris[:, 1] = p[1:-1]
    tris[:, 2] = p[2:]
    return tris


def _quad(p0, p1, p2, p3, direction) -> np.ndarray:
    return _fan([p0, p1, p2, p3], direction)


def _quads(q: np.ndarray, direction) -> np.ndarray:
    """(n, 4, 3) convex planar quads -> (2n, 3, 3) triangles facing ``direction`` ((3,) or (n, 3))."""
    q = np.asarray(q, dtype=float)
    d = np.broadcast_to(np.asarray(direction, dtype=float), (len(q), 3))
    tris = np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]])
    return _facing(tris, np.concatenate([d, d]))


def _box_tris(x0, x1, y0, y1, z0, z1) -> np.ndarray:
    c = np.array([[x, y, z] for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)], dtype=float)
    quads = ((0, 1, 3, 2), (4, 5, 7, 6), (0, 1, 5, 4), (2, 3, 7, 6), (0, 2, 6, 4), (1, 3, 7, 5))
    tris = np.concatenate([c[[[a, b, d], [a, d, e]]] for a, b, d, e in quads])
    return _outward(tris, c.mean(axis=0))


def _hull_tris(points) -> np.ndarray:
    """The convex hull's triangles of ``points`` (n, 3), wound outwards (zero-area ones dropped)."""
    p = np.asarray(points, dtype=float)
    tris = p[ConvexHull(p).simplices]
    area = np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1)
    return _outward(tris[area > 1e-12], p.mean(axis=0))


def _rect_x(x: float, y0: float, y1: float, z0: float, z1: float, facing: float) -> np.ndarray:
    """A rectangle in the plane X = x facing +X (facing > 0) or -X."""
    return _quad((x, y0, z0), (x, y1, z0), (x, y1, z1), (x, y0, z1), (facing, 0, 0))


def _rect_y(y: float, x0: float, x1: float, z0: float, z1: float, facing: float) -> np.ndarray:
    return _quad((x0, y, z0), (x1, y, z0), (x1, y, z1), (x0, y, z1), (0, facing, 0))


def _octagon(z, x_r, x_f, y_s, c_r, c_f) -> np.ndarray:
    """(8, 3) plan ring at height z, counter-clockwise from above: rear-right chamfer start first.

    Edges (ring[i] -> ring[i+1]): 0 rear-right chamfer, 1 right side, 2 front-right chamfer, 3 front,
    4 front-left chamfer, 5 left side, 6 rear-left chamfer, 7 rear."""
    return np.array([(x_r, -(y_s - c_r), z), (x_r + c_r, -y_s, z), (x_f - c_f, -y_s, z), (x_f, -(y_s - c_f), z),
                     (x_f, y_s - c_f, z), (x_f - c_f, y_s, z), (x_r + c_r, y_s, z), (x_r, y_s - c_r, z)])


def _band(lo: np.ndarray, hi: np.ndarray, i: int) -> tuple[np.ndarray, np.ndarray]:
    """Corners (p00, p10, p01, p11) of face ``i`` between rings ``lo`` and ``hi`` and its outward plan normal."""
    j = (i + 1) % len(lo)
    e = lo[j] - lo[i]
    out = np.array([e[1], -e[0], 0.0])
    return np.array([lo[i], lo[j], hi[i], hi[j]]), out / np.linalg.norm(out)


def _bilinear(c: np.ndarray, s: float, t: float) -> np.ndarray:
    return (1 - t) * ((1 - s) * c[0] + s * c[1]) + t * ((1 - s) * c[2] + s * c[3])


def _grid(c: np.ndarray, out: np.ndarray, s_breaks, t_breaks):
    """Cells (i, j, triangles) of a face with corners ``c`` cut at fractions ``s_breaks`` along, ``t_breaks`` up."""
    for i in range(len(s_breaks) - 1):
        for j in range(len(t_breaks) - 1):
            s0, s1, t0, t1 = s_breaks[i], s_breaks[i + 1], t_breaks[j], t_breaks[j + 1]
            pts = [_bilinear(c, s0, t0), _bilinear(c, s1, t0), _bilinear(c, s1, t1), _bilinear(c, s0, t1)]
            yield i, j, _quad(*pts, out)


def _loft(parts: _Parts, rings: list[np.ndarray], colour_of, material_of, bottom=None, top=None) -> None:
    """Side faces between consecutive rings (``colour_of(k, i)`` -> (colour, grime), ``material_of(k, i)``),
    plus optional bottom/top caps (colour, material)."""
    for k in range(len(rings) - 1):
        for i in range(len(rings[k])):
            c, out = _band(rings[k], rings[k + 1], i)
            if np.linalg.norm(c[0] - c[1]) < 1e-9 and np.linalg.norm(c[2] - c[3]) < 1e-9:
                continue
            colour, grime = colour_of(k, i)
            parts.add(_quad(c[0], c[1], c[3], c[2], out), colour, material_of(k, i), grime)
    if bottom is not None:
        parts.add(_fan(rings[0], (0, 0, -1)), *bottom)
    if top is not None:
        parts.add(_fan(rings[-1], (0, 0, 1)), *top)


def _with_levels(levels: list[float], rings: list[np.ndarray], extra: list[float]):
    """``rings`` (at ``levels``) with rings interpolated at the heights ``extra`` inserted."""
    zs, out = list(levels), list(rings)
    for z in sorted(extra):
        if any(abs(z - q) < 2e-3 for q in zs) or not zs[0] < z < zs[-1]:
            continue
        k = int(np.searchsorted(zs, z)) - 1
        f = (z - zs[k]) / (zs[k + 1] - zs[k])
        out.insert(k + 1, (1 - f) * out[k] + f * out[k + 1])
        zs.insert(k + 1, z)
    return zs, out


def _grime_of(z_top: float, z0: float, dirt: float) -> float:
    """Grime strength of a band ending at ``z_top`` (m) of a body whose lowest painted edge is ``z0``."""
    if dirt <= 0:
        return 0.0
    h = 0.10 + 0.45 * dirt
    s = 0.35 + 0.5 * dirt
    if z_top <= z0 + h / 2 + 1e-6:
        return s
    return 0.5 * s if z_top <= z0 + h + 1e-6 else 0.0


def _dirt_levels(z0: float, dirt: float) -> list[float]:
    if dirt <= 0:
        return []
    h = 0.10 + 0.45 * dirt
    return [z0 + h / 2, z0 + h]


def _wheel_parts(parts: _Parts, x: float, side: int, y_out: float, width: float, r: float, rim_rgb,
                 detailed_rim: bool = True, dirt: float = 0.0) -> None:
    """A tyre (tread, sidewall with a recessed rim, inner face) with its axis along Y, outer face at |Y| = y_out,
    a vertex straight down (it touches the ground at X = x, Z = 0)."""
    n = DETAILED_SECTIONS
    ang = -np.pi / 2 + np.arange(n + 1) * 2 * np.pi / n
    cs, sn = np.cos(ang), np.sin(ang)
    y_in = y_out - width
    out = (0.0, float(side), 0.0)

    def ring(rad, y):   # (n + 1, 3) points of a circle of radius rad in the plane |Y| = y
        return np.stack([x + rad * cs, np.full(n + 1, side * y), r + rad * sn], axis=-1)

    def band(a, b):     # quads between consecutive points of two rings
        return np.stack([a[:-1], b[:-1], b[1:], a[1:]], axis=1)

    radial = np.stack([cs[:-1] + cs[1:], np.zeros(n), sn[:-1] + sn[1:]], axis=-1)
    parts.add(_quads(band(ring(r, y_in), ring(r, y_out)), radial), TYRE, TYRE_MAT)
    parts.add(_fan(ring(r, y_in)[:-1], (0, -side, 0)), TYRE, TYRE_MAT)
    if not detailed_rim:
        parts.add(_fan(ring(r, y_out)[:-1], out), TYRE, TYRE_MAT)
        return
    r_rim, depth = 0.64 * r, 0.014
    y_rim = y_out - depth
    parts.add(_quads(band(ring(r_rim, y_out), ring(r, y_out)), out), TYRE, TYRE_MAT)
    parts.add(_quads(band(ring(r_rim, y_rim), ring(r_rim, y_out)), -radial), RECESS, TRIM_MAT)
    rim = tuple(np.asarray(rim_rgb, float) * (1 - 0.5 * dirt) + np.asarray(MUD, float) * 0.5 * dirt)
    # a lip, spokes with the dark gaps between them, a hub
    parts.add(_quads(band(ring(0.86 * r_rim, y_rim), ring(r_rim, y_rim)), out), rim, RIM_MAT)
    spokes = band(ring(0.3 * r_rim, y_rim), ring(0.86 * r_rim, y_rim))
    parts.add(_quads(spokes[0::2], out), rim, RIM_MAT)
    parts.add(_quads(spokes[1::2], out), RECESS, TRIM_MAT)
    parts.add(_fan(ring(0.3 * r_rim, y_rim)[:-1], out), rim, RIM_MAT)


def _plate(parts: _Parts, x_face: float, facing: int, z0: float, z1: float, colour, rng: np.random.Generator,
           y_half: float = 0.26, chars: int = 7) -> None:
    """A number plate: a thin box whose outer face is at X = x_face (``facing`` -1 rear, +1 front), an EU band,
    dark seven-segment characters 6 mm proud of it (the outermost part, at X = x_face + 6 mm * facing)."""
    t = 0.01
    x_in = x_face - facing * t
    parts.add(_box_tris(min(x_in, x_face), max(x_in, x_face), -y_half, y_half, z0, z1), colour, PLATE_MAT)
    xd = x_face + facing * 0.006
    # The band is on the viewer's left: +Y seen from behind (viewer faces +X), -Y from the front.
    band_y = (y_half - 0.045, y_half) if facing < 0 else (-y_half, -y_half + 0.045)
    parts.add(_rect_x(xd, *band_y, z0, z1, facing), PLATE_BLUE, PLATE_MAT)
    y_left, y_right = (-y_half + 0.02, y_half - 0.06) if facing < 0 else (-y_half + 0.06, y_half - 0.02)
    cell = (y_right - y_left) / chars
    h = (z1 - z0) * 0.68
    zc0 = z0 + (z1 - z0 - h) / 2
    for k in range(chars):
        mask = _DIGITS[int(rng.integers(len(_DIGITS)))]
        # characters run left to right as the viewer sees them: from +Y to -Y seen from behind
        ya, yb = (y_right - (k + 1) * cell, y_right - k * cell) if facing < 0 else (y_left + k * cell,
                                                                                     y_left + (k + 1) * cell)
        for seg, (u0, u1, v0, v1) in enumerate(_SEGMENTS):
            if not mask >> seg & 1:
                continue
            if facing < 0:   # seen from behind, the cell's u runs towards -Y
                y0, y1 = yb - u1 * (yb - ya) * 0.8 - 0.1 * cell, yb - u0 * (yb - ya) * 0.8 - 0.1 * cell
            else:
                y0, y1 = ya + u0 * (yb - ya) * 0.8 + 0.1 * cell, ya + u1 * (yb - ya) * 0.8 + 0.1 * cell
            parts.add(_rect_x(xd, y0, y1, zc0 + v0 * h, zc0 + v1 * h, facing), GAP, TRIM_MAT)


def _arch(parts: _Parts, x: float, side: int, y: float, r: float, radius: float, z_min: float) -> None:
    """A dark wheel-arch recess: the part of the disc of ``radius`` about (x, r) above ``z_min``, in the plane
    |Y| = y facing out."""
    th0 = math.asin(max(-1.0, min(1.0, (z_min - r) / radius)))
    th = np.linspace(th0, math.pi - th0, 13)
    pts = np.stack([x + radius * np.cos(th), np.full_like(th, side * y), r + radius * np.sin(th)], axis=-1)
    parts.add(_fan(pts, (0, side, 0)), RECESS, TRIM_MAT)


def _contact_shadow(parts: _Parts, hl: float, hw: float, inset_outer: tuple[float, float],
                    inset_inner: tuple[float, float]) -> None:
    """The dark ground under the body (ambient occlusion): two upward quads 12 and 24 mm above the ground."""
    for (ix, iy), z, rgb in ((inset_outer, 0.012, SHADOW_OUTER), (inset_inner, 0.024, SHADOW_INNER)):
        x0, x1, y0, y1 = -hl + ix, hl - ix, -hw + iy, hw - iy
        parts.add(_quad((x0, y0, z), (x1, y0, z), (x1, y1, z), (x0, y1, z), (0, 0, 1)), rgb, SHADOW_MAT)


def _decal(c: np.ndarray, out: np.ndarray, s0, s1, t0, t1, offset: float) -> np.ndarray:
    """A quad on the planar face with corners ``c`` (bilinear fractions s along, t up), ``offset`` m proud of it."""
    n = np.cross(c[1] - c[0], c[2] - c[0])
    n = n / np.linalg.norm(n)
    n = n if n @ out > 0 else -n
    pts = [_bilinear(c, s, t) + offset * n for s, t in ((s0, t0), (s1, t0), (s1, t1), (s0, t1))]
    return _quad(*pts, n)


def _wrap_light(parts: _Parts, side: int, facing: int, x_face: float, y_face: float, chamfer: float, w: float,
                side_len: float, z_inner: tuple[float, float], z_outer: tuple[float, float], colour) -> None:
    """A lamp cluster wrapped round a chamfered corner: ``w`` m along the end face (X = x_face, facing -X for the
    rear, +X for the front), across the chamfer, ``side_len`` m along the side (|Y| = y_face); 12 mm proud.
    Its height runs linearly from ``z_inner`` (lo, hi) at the inner end to ``z_outer`` at the side end."""
    f = float(facing)
    a = np.array([x_face, y_face - chamfer])
    b = np.array([x_face - f * chamfer, y_face])
    path = [(np.array([x_face, y_face - chamfer - w]), [(f, 0.0)]), (a, [(f, 0.0), (f, 1.0)]),
            (b, [(f, 1.0), (0.0, 1.0)]), (np.array([x_face - f * (chamfer + side_len), y_face]), [(0.0, 1.0)])]
    lengths = np.r_[0.0, np.cumsum([w, chamfer * math.sqrt(2), side_len])]
    pts = []
    for (p, normals), u in zip(path, lengths / lengths[-1]):
        zl = (1 - u) * z_inner[0] + u * z_outer[0]
        zh = (1 - u) * z_inner[1] + u * z_outer[1]
        for nx, ny in normals:
            nrm = np.array([nx, ny]) / math.hypot(nx, ny)
            for off in (0.012, -0.02):
                q = p + off * nrm
                pts += [(q[0], side * q[1], zl), (q[0], side * q[1], zh)]
    parts.add(_hull_tris(pts), colour, LIGHT_MAT)


#: Car (not van) body proportions (m): ``nose``/``tail`` how far the belt-line edge of the bonnet/boot lies behind
#: the front/rear face (a rounded nose and boot), ``belt_in`` the shoulder's inset at the belt, ``glass_in`` the
#: glass's inset from the body side at the belt, ``tumble`` how far the side glass leans in up to ``roof_round``
#: below the roof, ``roof_in`` the roof's inset from the body side, ``roof_rx``/``roof_fx`` its rear/front
#: chamfers, ``screen_run`` the windscreen's run from its base to its top.
_CAR_BODY = dict(nose=0.55, tail=0.15, belt_in=0.05, glass_in=0.11, tumble=0.22, roof_in=0.33, roof_round=0.07,
                 roof_rx=0.12, roof_fx=0.12, screen_run=0.80)
#: Per car style: (rear glass base, rear glass top) ahead of the rear face (m): the rear window's rake. An SUV has
#: an estate's long roof over a steeper tailgate; a pickup's cab starts above its bed (:attr:`VehicleLayout.cab_length`).
_CAR_REAR = {"hatch": (0.18, 1.00), "sedan": (0.75, 1.45), "estate": (0.15, 0.62), "suv": (0.14, 0.48)}
#: Per style, what differs from :data:`_CAR_BODY`: an SUV's blunter nose and upright tailgate, a pickup's flat
#: tailgate and upright cab.
_STYLE_BODY = {"suv": dict(nose=0.45, tail=0.08, tumble=0.16, roof_in=0.27, screen_run=0.72),
               "pickup": dict(nose=0.45, tail=0.03, tumble=0.14, roof_in=0.25, screen_run=0.70, roof_rx=0.05)}
#: The style of a car body type.
_BODY_STYLE = {"hatchback": "hatch", "saloon": "sedan", "estate": "estate", "suv": "suv", "van": "van",
               "pickup": "pickup"}


def _car_parts(length: float, width: float, dirt: float, rng: np.random.Generator, body: str | None = None) -> _Parts:
    """A detailed car, van or pickup (the shape of :func:`vehicle_layout`): see :func:`vehicle_faces_detailed`."""
    L = vehicle_layout(length, width, body)
    hl, hw, H, r = length / 2, width / 2, L.roof, L.wheel_radius
    hb = hw - 0.085                                    # body side; the mirrors reach out to hw
    if body is None:
        van = H > 1.8
        style = "van" if van else ("hatch" if length < 4.3 else str(rng.choice(["hatch", "sedan", "estate"])))
        lift = rise = 0.0
    else:
        style = _BODY_STYLE[body]
        van = style == "van"
        lift = round(L.clearance - 0.17, 3)           # bumpers, plates, intakes with the body's ground clearance
        rise = round(max(lift, L.belt - 0.95), 3)     # lamps with its belt line
    z_cl, z0, z_bt, belt = L.clearance, 0.30 + lift, 0.56 + lift, L.belt
    z_st, z_sh = z_bt + 0.025, belt - (0.02 if van else 0.12)
    c_r, c_f = 0.10, (0.10 if van else 0.20)
    parts = _Parts()
    # lower body: bumper (rear face at -hl), a 3 cm step to the tailgate, shoulder
    levels = [z0, z_bt, z_st, z_sh, belt]
    rings = [_octagon(z0, -hl, hl - 0.015, hb, c_r, c_f), _octagon(z_bt, -hl, hl - 0.015, hb, c_r, c_f),
             _octagon(z_st, -hl + 0.03, hl - 0.03, hb, c_r, c_f), _octagon(z_sh, -hl + 0.03, hl - 0.03, hb, c_r, c_f)]
    if van:
        rings.append(_octagon(belt, -hl + 0.03, hl - 0.04, hb - 0.01, c_r, c_f))
    else:   # rounded nose and boot: the bonnet falls towards the front, the deck's rear edge is chamfered
        p = {**_CAR_BODY, **_STYLE_BODY.get(style, {})}
        z_mid = 0.5 * (z_sh + belt)
        levels.insert(-1, z_mid)
        rings += [_octagon(z_mid, -hl + 0.03 + 0.4 * p["tail"], hl - 0.03 - 0.3 * p["nose"], hb - 0.4 * p["belt_in"],
                           c_r, c_f),
                  _octagon(belt, -hl + 0.03 + p["tail"], hl - 0.03 - p["nose"], hb - p["belt_in"], c_r, c_f)]
    levels, rings = _with_levels(levels, rings, _dirt_levels(z0, dirt))

    def body_colour(k, i):
        return _PAINT, _grime_of(levels[k + 1], z0, dirt)

    _loft(parts, rings, body_colour, lambda k, i: DIRT_MAT if _grime_of(levels[k + 1], z0, dirt) else PAINT_MAT,
          bottom=(TRIM_BLACK, TRIM_MAT), top=(_PAINT, PAINT_MAT))
    # dark sill, lower valance and underbody tray
    tray = [_octagon(z_cl, -hl + 0.32, hl - 0.30, hb - 0.07, 0.05, 0.05),
            _octagon(z0, -hl + 0.015, hl - 0.03, hb - 0.004, c_r, c_f)]
    _loft(parts, tray, lambda k, i: (TRIM_BLACK, 0.3 * dirt), lambda k, i: TRIM_MAT, bottom=(TRIM_BLACK, TRIM_MAT))
    # greenhouse: glass cells separated by pillars (paint), a roof rail band and the roof
    b_len = float(np.clip(0.30 * length - 0.25, 0.85, 1.35))
    if van:
        rb, rt, fb, ft = -hl + 0.03, -hl + 0.09, hl - 0.80, hl - 1.50
        y0, y1, y2, z1 = hb - 0.01, hb - 0.05, hb - 0.10, H - 0.06
    else:
        fb = hl - b_len
        ft = fb - p["screen_run"]
        if style == "pickup":    # the cab's rear wall stands at the front of the bed
            rb = -hl + round(length - L.cab_length, 3)
            rt = rb + 0.10
        else:
            rb, rt = (-hl + u for u in _CAR_REAR[style])
        y0, y1, y2, z1 = hb - p["glass_in"], hb - p["glass_in"] - p["tumble"], hb - p["roof_in"], H - p["roof_round"]

    def rect(z, xr, xf, y):
        return np.array([(xr, -y, z), (xf, -y, z), (xf, y, z), (xr, y, z)])

    rx, fx = (0.05, 0.07) if van else (p["roof_rx"], p["roof_fx"])
    cab = [rect(belt, rb, fb, y0), rect(z1, rt, ft, y1), rect(H, rt + rx, ft - fx, y2)]
    side_br, side_glass, side_t = {
        "hatch": ([0, .30, .54, .59, .93, 1], {1, 3}, [0, .09, .92, 1]),
        "sedan": ([0, .22, .52, .57, .93, 1], {1, 3}, [0, .09, .92, 1]),
        "estate": ([0, .09, .25, .29, .53, .58, .93, 1], {1, 3, 5}, [0, .09, .92, 1]),
        "suv": ([0, .08, .24, .28, .53, .58, .93, 1], {1, 3, 5}, [0, .08, .92, 1]),
        "pickup": ([0, .08, .47, .52, .93, 1], {1, 3}, [0, .08, .92, 1]),
        "van": ([0, .74, .77, .95, 1], {2}, [0, .06, .62, 1])}[style]
    a = {"hatch": 0.11, "sedan": 0.12, "estate": 0.085, "suv": 0.09, "pickup": 0.12, "van": 0.05}[style]
    if van:
        rear_s, rear_t, rear_cells, gap_cells = [0, a, .49, .51, 1 - a, 1], [0, .40, .88, 1], {(1, 1), (3, 1)}, {2}
    else:
        rear_s, rear_t, rear_cells, gap_cells = [0, a, 1 - a, 1], [0, .08, .95, 1], {(1, 1)}, set()
    n_side = len(side_br) - 1
    faces = {0: (side_br, side_t, {(i, 1) for i in side_glass}, set()),
             1: ([0, .07, .93, 1], [0, .03, .96, 1], {(1, 1)}, set()),
             2: ([1 - b for b in reversed(side_br)], side_t, {(n_side - 1 - i, 1) for i in side_glass}, set()),
             3: (rear_s, rear_t, rear_cells, gap_cells)}
    for i, (s_br, t_br, glass, gaps) in faces.items():
        c, out = _band(cab[0], cab[1], i)
        c = c[[0, 1, 2, 3]]
        for ci, cj, tris in _grid(c, out, s_br, t_br):
            if (ci, cj) in glass:
                parts.add(tris, GLASS_TINT, GLASS_MAT)
            elif ci in gaps:
                parts.add(tris, GAP, TRIM_MAT)
            else:
                parts.add(tris, _PAINT, PAINT_MAT)
        if i == 3 and not van:   # high-mounted brake lamp at the top of the rear window
            parts.add(_decal(c, out, .42, .58, .86, .93, 0.008), LAMP_BRAKE, LIGHT_MAT)
    _loft(parts, cab[1:], lambda k, i: (_PAINT, 0.0), lambda k, i: PAINT_MAT, top=(_PAINT, PAINT_MAT))
    # mirrors: the widest part, out to |Y| = hw
    xm, zm, hm = fb - 0.02, belt + (0.08 if van else 0.03), (0.26 if van else 0.12)
    mirror_rgb = _PAINT if rng.uniform() < 0.8 else TRIM_BLACK
    for side in (-1, 1):
        yi = hb - 0.06
        pts = [(xm, side * yi, zm), (xm + 0.17, side * yi, zm), (xm, side * yi, zm + hm),
               (xm + 0.17, side * yi, zm + hm),
               (xm, side * hw, zm + 0.01), (xm + 0.11, side * hw, zm + 0.01), (xm, side * hw, zm + hm + 0.02),
               (xm + 0.09, side * hw, zm + hm + 0.02)]
        parts.add(_hull_tris(pts), mirror_rgb, PAINT_MAT if mirror_rgb == _PAINT else TRIM_MAT)
        ya, yb = sorted((side * (hb + 0.01), side * (hw - 0.012)))
        parts.add(_rect_x(xm - 0.006, ya, yb, zm + 0.025, zm + hm - 0.005, -1), GLASS_TINT, GLASS_MAT)
    # wheels under dark arches
    axles = [L.rear_axle_x, L.front_axle_x]
    rim_rgb = RIMS[int(rng.integers(len(RIMS)))]
    y_tyre = hb + 0.04
    for ax in axles:
        for side in (-1, 1):
            _arch(parts, ax, side, hb + 0.012, r, r + 0.075, z0)
            _wheel_parts(parts, ax, side, y_tyre, L.wheel_width, r, rim_rgb, True, dirt)
    # panel gaps and door handles on the sides
    arch_r = r + 0.075
    if van:
        x_fd = min(fb - 0.05, L.front_axle_x - arch_r - 0.05)
        x_b = x_fd - 1.0
        lines, handles = [x_fd, x_b, x_b - 1.1], [x_b + 0.08, x_b - 1.0]
    else:
        x_fd = min(fb + 0.03, L.front_axle_x - arch_r - 0.05)
        x_b = rb + 0.545 * (fb - rb)
        c_end = side_br[3] if style in ("estate", "suv") else side_br[1]
        x_rd = max(rb + c_end * (fb - rb), L.rear_axle_x + arch_r + 0.05)
        lines, handles = [x_fd, x_b, x_rd], [x_b - 0.20, x_rd + 0.06]
    for side in (-1, 1):
        for x in lines:
            parts.add(_rect_y(side * (hb + 0.006), x - 0.006, x + 0.006, z0 + 0.02, z_sh - 0.01, side), GAP, TRIM_MAT)
        for x in handles:
            parts.add(_rect_y(side * (hb + 0.006), x, x + 0.14, z_sh - 0.09, z_sh - 0.06, side), (60, 60, 62), TRIM_MAT)
    # rear: tail lights round the corners, plate in a dark recess, exhaust
    x_rear = -hl + 0.03
    if van:
        w, zi, zo = float(rng.uniform(0.12, 0.16)), (0.62 + rise, 0.92 + rise), (0.60 + rise, 0.93 + rise)
    elif style == "pickup":   # tall narrow clusters at the tailgate's corners
        w, zi, zo = float(rng.uniform(0.12, 0.16)), (0.66 + rise, 0.90 + rise), (0.64 + rise, 0.91 + rise)
    else:
        w, zi, zo = float(rng.uniform(0.26, 0.40)), (0.68 + rise, 0.80 + rise), (0.64 + rise, 0.82 + rise)
    x_lamp = x_rear - 0.018
    y_inner = hb - c_r - w
    for side in (-1, 1):
        _wrap_light(parts, side, -1, x_rear, hb, c_r, w, 0.05, zi, zo, LAMP_TAIL)

        def lamp(u0, u1, za, zb, rgb):
            ya, yb = sorted((side * (y_inner + u0), side * (y_inner + u1)))
            parts.add(_rect_x(x_lamp, ya, yb, za, zb, -1), rgb, LIGHT_MAT)

        if van or style == "pickup":
            lamp(0.015, w - 0.015, zi[1] - 0.12, zi[1] - 0.015, LAMP_BRAKE)
            lamp(0.015, w - 0.015, zi[0] + 0.14, zi[0] + 0.22, LAMP_AMBER)
            lamp(0.015, w - 0.015, zi[0] + 0.02, zi[0] + 0.12, LAMP_WHITE)
        else:
            lamp(0.02, 0.02 + 0.28 * w, zi[0] + 0.02, zi[1] - 0.02, LAMP_WHITE)
            lamp(0.35 * w, 0.95 * w, zi[1] - 0.055, zi[1] - 0.015, LAMP_BRAKE)
            lamp(0.35 * w, 0.95 * w, zi[0] + 0.02, zi[0] + 0.05, LAMP_AMBER)
    parts.add(_rect_x(-hl + 0.022, -0.29, 0.29, 0.60 + lift, 0.74 + lift, -1), TRIM_BLACK, TRIM_MAT)
    rear_plate = PLATE_YELLOW if rng.uniform() < 0.3 else PLATE_WHITE
    _plate(parts, -hl + 0.016, -1, 0.615 + lift, 0.725 + lift, rear_plate, rng)
    ex_y = -(hb - 0.32)
    parts.add(_box_tris(-hl + 0.012, -hl + 0.22, ex_y - 0.045, ex_y + 0.045, 0.205 + lift, 0.265 + lift), (70, 70, 72),
              TRIM_MAT)
    if style == "pickup":   # the open bed: its dark floor and liner seen from above, inside the rails
        yl, xl0, xl1, zl = hb - p["belt_in"] - 0.07, -hl + 0.03 + p["tail"] + 0.06, rb - 0.06, belt + 0.004
        parts.add(_quad((xl0, -yl, zl), (xl1, -yl, zl), (xl1, yl, zl), (xl0, yl, zl), (0, 0, 1)), (34, 34, 36), TRIM_MAT)
        for x in np.linspace(xl0 + 0.15, xl1 - 0.15, 5):   # ribs of the liner
            parts.add(_quad((x - 0.02, -yl, zl + 0.002), (x + 0.02, -yl, zl + 0.002), (x + 0.02, yl, zl + 0.002),
                            (x - 0.02, yl, zl + 0.002), (0, 0, 1)), (55, 55, 57), TRIM_MAT)
    # front: head lights, grille, lower intake, plate (its characters are the front-most part, at +hl)
    x_front = hl - 0.03
    wh = 0.30 if not van else 0.22
    for side in (-1, 1):
        _wrap_light(parts, side, 1, x_front, hb, c_f, wh, 0.04, (0.66 + rise, 0.76 + rise), (0.68 + rise, 0.78 + rise),
                    LAMP_HEAD)
        yg0, yg1 = sorted((side * 0.28, side * (hb - 0.28)))
        parts.add(_rect_x(hl - 0.007, yg0, yg1, 0.33 + lift, 0.50 + lift, 1), RECESS, TRIM_MAT)
    yg = hb - c_f - wh - 0.03
    parts.add(_rect_x(x_front + 0.008, -yg, yg, 0.62 + lift, 0.75 + rise, 1), (30, 30, 32), TRIM_MAT)
    parts.add(_rect_x(hl - 0.007, -(hb - 0.28), hb - 0.28, 0.31 + lift, 0.35 + lift, 1), RECESS, TRIM_MAT)
    _plate(parts, hl - 0.006, 1, 0.37 + lift, 0.48 + lift, PLATE_WHITE, rng)
    _contact_shadow(parts, hl, hw, (0.05, 0.105), (0.35, 0.305))
    return parts


def _truck_parts(length: float, width: float, dirt: float, rng: np.random.Generator, body: str | None = None) -> _Parts:
    """A detailed truck: cab, box or curtain-sider body with rear doors, chassis, under-run bar, light bar,
    mud flaps, twin rear tyres (the shape of :func:`vehicle_layout`). An artic (``body`` ``"artic"``): a tractor
    and its semi-trailer as one rigid footprint, the trailer's box ending 0.75 m behind the cab, the tractor's
    drive axle under the trailer's nose, the trailer's axle group at its rear."""
    L = vehicle_layout(length, width, body)
    hl, hw, H, r = length / 2, width / 2, L.roof, L.wheel_radius
    artic = body == "artic"
    parts = _Parts()
    cab_len = 2.3
    x_c0, yc = hl - cab_len, hw - 0.10
    z_cr = float(rng.uniform(2.9, 3.1))
    curtain = bool(rng.uniform() < 0.45)
    box_rgb = TRUCK_BOXES[int(rng.integers(len(TRUCK_BOXES)))]
    box = _PAINT if box_rgb is None else box_rgb
    grey, dark = (150, 152, 155), (34, 34, 36)
    # -------- body: box or curtains between rails and corner posts; rear doors with bars and hinges
    xb0, xb1, zb0, zb1 = -hl + 0.045, x_c0 - (0.75 if artic else 0.15), 1.15, H - 0.02
    yb = hw - 0.01
    parts.add(_quad((xb0, -yb, zb1), (xb1, -yb, zb1), (xb1, yb, zb1), (xb0, yb, zb1), (0, 0, 1)), box, PAINT_MAT)
    parts.add(_quad((xb0, -yb, zb0), (xb1, -yb, zb0), (xb1, yb, zb0), (xb0, yb, zb0), (0, 0, -1)), dark, TRIM_MAT)
    parts.add(_rect_x(xb1, -yb, yb, zb0, zb1, 1), box, PAINT_MAT)
    z_c0, z_c1 = 1.28, round(H - 0.15, 6)
    for side in (-1, 1):
        if curtain:
            xs = np.linspace(-hl + 0.07, xb1, max(2, int(round((xb1 + hl - 0.07) / 0.30))) + 1)
            ys = np.where(np.arange(len(xs)) % 2 == 0, hw - 0.01, hw - 0.04)
            for k in range(len(xs) - 1):
                q = [(xs[k], side * ys[k], z_c0), (xs[k + 1], side * ys[k + 1], z_c0),
                     (xs[k + 1], side * ys[k + 1], z_c1), (xs[k], side * ys[k], z_c1)]
                parts.add(_quad(*q, (0, side, 0)), box, PAINT_MAT)
            for x in xs[2:-1:4]:
                parts.add(_rect_y(side * (hw - 0.004), x - 0.02, x + 0.02, z_c0, z_c1, side), (60, 60, 65), TRIM_MAT)
            parts.add(_rect_y(side * (hw - 0.04), xb0, -hl + 0.07, z_c0, z_c1, side), dark, TRIM_MAT)
        else:
            parts.add(_rect_y(side * yb, xb0, xb1, z_c0, z_c1, side), box, PAINT_MAT)
        ya, yb_ = sorted((side * (hw - 0.03), side * hw))
        parts.add(_box_tris(-hl + 0.07, xb1, ya, yb_, zb0, z_c0), grey, TRIM_MAT)        # bottom rail
        parts.add(_box_tris(-hl + 0.07, xb1, ya, yb_, z_c1, H), grey, TRIM_MAT)          # top rail
        ya, yb_ = sorted((side * (hw - 0.08), side * hw))
        parts.add(_box_tris(-hl, -hl + 0.07, ya, yb_, zb0, H), grey, TRIM_MAT)          # rear corner post
    parts.add(_box_tris(-hl, -hl + 0.07, -(hw - 0.08), hw - 0.08, z_c1, H), grey, TRIM_MAT)      # header
    parts.add(_box_tris(-hl, -hl + 0.07, -(hw - 0.08), hw - 0.08, zb0, 1.26), grey, TRIM_MAT)    # sill
    dw = hw - 0.08
    parts.add(_rect_x(-hl + 0.045, -dw, dw, 1.26, z_c1, -1), box, PAINT_MAT)
    if dirt > 0:
        h = 0.15 + 0.6 * dirt
        s = 0.35 + 0.5 * dirt
        for z0_, z1_, g in ((1.26, 1.26 + h / 2, s), (1.26 + h / 2, 1.26 + h, s / 2)):
            parts.add(_rect_x(-hl + 0.036, -dw, dw, z0_, z1_, -1), box, DIRT_MAT, g)
    parts.add(_rect_x(-hl + 0.030, -0.008, 0.008, 1.26, z_c1, -1), GAP, TRIM_MAT)
    for yy in (0.30 * dw, 0.72 * dw):
        for side in (-1, 1):
            y0, y1 = sorted((side * (yy - 0.018), side * (yy + 0.018)))
            parts.add(_box_tris(-hl + 0.008, -hl + 0.030, y0, y1, 1.30, round(H - 0.2, 6)), (160, 162, 165), TRIM_MAT)
            y0, y1 = sorted((side * (yy - 0.02), side * (yy + 0.10)))
            parts.add(_box_tris(-hl, -hl + 0.008, y0, y1, 1.95, 2.0), (160, 162, 165), TRIM_MAT)
    for side in (-1, 1):
        y0, y1 = sorted((side * (hw - 0.18), side * (hw - 0.08)))
        for z in (1.5, 2.3, 3.1):
            parts.add(_box_tris(-hl + 0.015, -hl + 0.036, y0, y1, z, z + 0.08), (120, 122, 125), TRIM_MAT)
    # -------- chassis, the dark underside behind the rear axle, under-run bar, light bar, plate
    for side in (-1, 1):
        y0, y1 = sorted((side * 0.38, side * 0.48))
        parts.add(_box_tris(-hl + 0.25, hl - 0.30, y0, y1, 0.62, 0.92), dark, TRIM_MAT)
        parts.add(_box_tris(-hl + 0.20, -hl + 0.30, y0, y1, 0.55, 0.75), dark, TRIM_MAT)       # bar supports
    parts.add(_box_tris(-hl + 0.25, -hl + 0.36, -0.48, 0.48, 0.62, 0.92), dark, TRIM_MAT)
    parts.add(_box_tris(xb0 + 0.25, xb1 - 0.05, -0.5, 0.5, 0.92, zb0), dark, TRIM_MAT)
    parts.add(_rect_x(L.rear_axle_x, -(hw - 0.66), hw - 0.66, 0.15, zb0, -1), RECESS, TRIM_MAT)
    parts.add(_box_tris(-hl + 0.08, -hl + 0.20, -(hw - 0.15), hw - 0.15, 0.40, 0.55), (50, 50, 52), TRIM_MAT)
    parts.add(_box_tris(-hl + 0.06, -hl + 0.16, -(hw - 0.04), hw - 0.04, 0.75, 0.95), (40, 40, 42), TRIM_MAT)
    for side in (-1, 1):
        for u0, u1, rgb in ((0.0, 0.10, LAMP_AMBER), (0.10, 0.26, LAMP_TAIL), (0.26, 0.34, LAMP_WHITE),
                            (0.34, 0.42, LAMP_BRAKE)):
            y0, y1 = sorted((side * (hw - 0.06 - u0), side * (hw - 0.06 - u1)))
            parts.add(_rect_x(-hl + 0.048, y0, y1, 0.79, 0.91, -1), rgb, LIGHT_MAT)
    rear_plate = PLATE_YELLOW if rng.uniform() < 0.4 else PLATE_WHITE
    _plate(parts, -hl + 0.048, -1, 0.795, 0.905, rear_plate, rng)
    # -------- wheels: twin tyres on the rear tandem, mud flaps and guards
    steel = ((190, 190, 188), (120, 122, 126))[int(rng.integers(2))]
    rear_axles = list(L.axles[:-1])
    group = rear_axles[:3] if artic else rear_axles      # the axles under the box (a trailer's group)
    g_end = rear_axles[-1] if artic else L.front_axle_x  # the side guards run from the group to here
    for ax in rear_axles:
        for side in (-1, 1):
            _wheel_parts(parts, ax, side, hw - 0.05, 0.28, r, steel, True, dirt)
            _wheel_parts(parts, ax, side, hw - 0.05 - 0.32, 0.28, r, steel, False, dirt)
    for side in (-1, 1):
        _wheel_parts(parts, L.front_axle_x, side, hw - 0.05, 0.30, r, steel, True, dirt)
        xf = L.rear_axle_x - r - 0.10
        y0, y1 = sorted((side * (hw - 0.05), side * (hw - 0.70)))
        parts.add(_box_tris(xf - 0.012, xf, y0, y1, 0.22, 1.05), (18, 18, 18), TYRE_MAT, 0.4 * dirt)
        y0, y1 = sorted((side * (hw - 0.68), side * (hw - 0.04)))
        parts.add(_box_tris(group[0] - 0.58, group[-1] + 0.58, y0, y1, 1.04, 1.10), (30, 30, 32), TRIM_MAT)
        g0, g1 = group[-1] + r + 0.25, g_end - r - 0.30
        if g1 - g0 > 0.5:
            y0, y1 = sorted((side * (hw - 0.07), side * (hw - 0.03)))
            for z0_, z1_ in ((0.50, 0.60), (0.82, 0.90)):
                parts.add(_box_tris(g0, g1, y0, y1, z0_, z1_), (120, 122, 125), TRIM_MAT)
            if side < 0 and g1 - g0 > 1.4:
                parts.add(_box_tris(g1 - 1.2, g1 - 0.1, -(hw - 0.12), -(hw - 0.65), 0.50, 1.0), (165, 167, 170),
                          RIM_MAT)
    # -------- cab: lower body, glass band (windscreen, door windows), roof, optional roof fairing
    levels = [0.55, 1.75, z_cr - 0.10, z_cr]
    rings = [_octagon(0.55, x_c0, hl - 0.03, yc, 0.02, 0.14), _octagon(1.75, x_c0, hl - 0.03, yc, 0.02, 0.14),
             _octagon(z_cr - 0.10, x_c0, hl - 0.16, yc - 0.03, 0.02, 0.14),
             _octagon(z_cr, x_c0, hl - 0.22, yc - 0.08, 0.02, 0.12)]
    low_levels, low = _with_levels(levels[:2], rings[:2], _dirt_levels(0.55, dirt))
    _loft(parts, low, lambda k, i: (_PAINT, _grime_of(low_levels[k + 1], 0.55, dirt)),
          lambda k, i: DIRT_MAT if _grime_of(low_levels[k + 1], 0.55, dirt) else PAINT_MAT,
          bottom=(dark, TRIM_MAT))
    door = [0, .42, .47, .95, 1]
    for i in range(8):
        c, out = _band(rings[1], rings[2], i)
        if i == 3:
            cells, s_br, t_br = {(1, 1)}, [0, .05, .95, 1], [0, .04, .93, 1]
        elif i == 1:
            cells, s_br, t_br = {(2, 1)}, door, [0, .05, .90, 1]
        elif i == 5:
            cells, s_br, t_br = {(1, 1)}, [1 - b for b in reversed(door)], [0, .05, .90, 1]
        else:
            cells, s_br, t_br = set(), [0, 1], [0, 1]
        for ci, cj, tris in _grid(c, out, s_br, t_br):
            glass = (ci, cj) in cells
            parts.add(tris, GLASS_TINT if glass else _PAINT, GLASS_MAT if glass else PAINT_MAT)
    _loft(parts, rings[2:], lambda k, i: (_PAINT, 0.0), lambda k, i: PAINT_MAT, top=(_PAINT, PAINT_MAT))
    if rng.uniform() < 0.6 or artic:     # a roof fairing (every tractor: up to its trailer's height)
        pts = [(x, s * y, z) for s in (-1, 1) for x, y, z in
               ((x_c0 + 0.10, yc - 0.10, z_cr), (hl - 0.9, yc - 0.12, z_cr), (x_c0 + 0.05, yc - 0.12, H - 0.08),
                (x_c0 + 0.55, yc - 0.14, H - 0.08))]
        parts.add(_hull_tris(pts), _PAINT, PAINT_MAT)
    for side in (-1, 1):
        _arch(parts, L.front_axle_x, side, yc + 0.012, r, r + 0.10, 0.55)
        for x in (hl - 0.35, x_c0 + 0.9):
            parts.add(_rect_y(side * (yc + 0.006), x - 0.007, x + 0.007, 1.12, 1.74, side), GAP, TRIM_MAT)
        y0, y1 = sorted((side * (hw - 0.09), side * hw))
        parts.add(_box_tris(hl - 0.50, hl - 0.40, y0, y1, 1.85, 2.55), TRIM_BLACK, TRIM_MAT)   # mirror head
        parts.add(_rect_x(hl - 0.506, *sorted((side * (hw - 0.08), side * (hw - 0.01))), 1.90, 2.50, -1),
                  GLASS_TINT, GLASS_MAT)
        y0, y1 = sorted((side * (yc - 0.05), side * (hw - 0.09)))
        for z in (1.90, 2.45):
            parts.add(_box_tris(hl - 0.47, hl - 0.43, y0, y1, z, z + 0.05), TRIM_BLACK, TRIM_MAT)
    # -------- front: bumper, head lamps (the front-most part, at +hl), grille, plate
    parts.add(_box_tris(hl - 0.22, hl - 0.012, -(yc - 0.02), yc - 0.02, 0.42, 0.80), (45, 45, 48), TRIM_MAT)
    for side in (-1, 1):
        y0, y1 = sorted((side * (yc - 0.48), side * (yc - 0.10)))
        parts.add(_box_tris(hl - 0.03, hl, y0, y1, 0.58, 0.72), LAMP_HEAD, LIGHT_MAT)
    parts.add(_rect_x(hl - 0.022, -(yc - 0.30), yc - 0.30, 0.90, 1.60, 1), (28, 28, 30), TRIM_MAT)
    for z in (1.05, 1.22, 1.39):
        parts.add(_rect_x(hl - 0.015, -(yc - 0.32), yc - 0.32, z, z + 0.04, 1), (90, 90, 92), TRIM_MAT)
    _plate(parts, hl - 0.006, 1, 0.47, 0.57, PLATE_WHITE, rng)
    _contact_shadow(parts, hl, hw, (0.10, 0.05), (0.60, 0.45))
    return parts


def _bus_parts(length: float, width: float, dirt: float, rng: np.random.Generator, body: str | None = "bus") -> _Parts:
    """A detailed bus or coach: a one-box body with rounded corners, a band of side windows between pillars
    from the belt line to 0.42 m below the roof, a windscreen with a destination display, a rear window over the
    engine grille, bumpers, lamps, plates, mirrors at the front corners, twin rear tyres (:func:`vehicle_layout`)."""
    L = vehicle_layout(length, width, "bus")
    hl, hw, H, r = length / 2, width / 2, L.roof, L.wheel_radius
    hb = hw - 0.07                       # body side; the mirrors reach out to hw
    z0, belt, z_wt, z_r = 0.40, L.belt, round(H - 0.42, 6), round(H - 0.10, 6)
    c = 0.14
    xr, xf = -hl + 0.02, hl - 0.02       # the body's end faces; bumpers and plates reach the footprint's ends
    parts = _Parts()
    grey, dark = (150, 152, 155), (34, 34, 36)
    steel = ((190, 190, 188), (120, 122, 126))[int(rng.integers(2))]
    # lower body, with grime at its foot; the dark underbody
    levels, rings = _with_levels([z0, belt], [_octagon(z0, xr, xf, hb, c, c), _octagon(belt, xr, xf, hb, c, c)],
                                 _dirt_levels(z0, dirt))
    _loft(parts, rings, lambda k, i: (_PAINT, _grime_of(levels[k + 1], z0, dirt)),
          lambda k, i: DIRT_MAT if _grime_of(levels[k + 1], z0, dirt) else PAINT_MAT, bottom=(dark, TRIM_MAT))
    tray = [_octagon(L.clearance, xr + 0.4, xf - 0.4, hb - 0.10, 0.05, 0.05), _octagon(z0, xr + 0.01, xf - 0.01,
                                                                                        hb - 0.01, c, c)]
    _loft(parts, tray, lambda k, i: (dark, 0.3 * dirt), lambda k, i: TRIM_MAT, bottom=(dark, TRIM_MAT))
    # window band: glass between pillars on the sides, the windscreen and display at the front, a rear window
    lo, hi = _octagon(belt, xr, xf, hb, c, c), _octagon(z_wt, xr, xf, hb, c, c)
    side_len = (xf - c) - (xr + c)
    n_win = max(3, int(round(side_len / 1.45)))
    pillar = 0.10 / side_len
    s_side = [0.0] + [v for k in range(1, n_win) for v in (k / n_win - pillar / 2, k / n_win + pillar / 2)] + [1.0]
    s_side = [0.0, 0.02] + s_side[1:-1] + [0.985, 1.0]
    for i in range(8):
        cq, out = _band(lo, hi, i)
        if i in (1, 5):
            cells = {(k, 1) for k in range(1, len(s_side) - 2, 2)}
            s_br, t_br = s_side, [0, .05, .93, 1]
        elif i == 3:
            cells, s_br, t_br = {(1, 1)}, [0, .03, .97, 1], [0, .02, .78, 1]
        elif i == 7:
            cells, s_br, t_br = {(1, 2)}, [0, .10, .90, 1], [0, .40, .55, .92, 1]
        else:
            cells, s_br, t_br = set(), [0, 1], [0, 1]
        for ci, cj, tris in _grid(cq, out, s_br, t_br):
            glass = (ci, cj) in cells
            parts.add(tris, GLASS_TINT if glass else _PAINT, GLASS_MAT if glass else PAINT_MAT)
        if i == 3:       # destination display above the windscreen glass
            parts.add(_decal(cq, out, .22, .78, .82, .96, 0.008), (20, 20, 22), TRIM_MAT)
            parts.add(_decal(cq, out, .30, .70, .86, .92, 0.012), LAMP_AMBER, LIGHT_MAT)
        if i == 7:       # engine grille below the rear window
            parts.add(_decal(cq, out, .20, .80, .06, .34, 0.008), RECESS, TRIM_MAT)
    # roof: a painted band, the rounded roof edge, the roof with a dark air-conditioning pod
    top = [hi, _octagon(z_r, xr + 0.04, xf - 0.06, hb - 0.05, c, c), _octagon(H, xr + 0.20, xf - 0.30, hb - 0.20, c, c)]
    _loft(parts, top, lambda k, i: (_PAINT, 0.0), lambda k, i: PAINT_MAT, top=(_PAINT, PAINT_MAT))
    # bumpers at the footprint's ends, lamps, plates
    parts.add(_box_tris(-hl, xr + 0.08, -(hb - 0.05), hb - 0.05, 0.40, 0.62), (45, 45, 48), TRIM_MAT)
    parts.add(_box_tris(xf - 0.08, hl - 0.012, -(hb - 0.05), hb - 0.05, 0.40, 0.62), (45, 45, 48), TRIM_MAT)
    for side in (-1, 1):
        y0, y1 = sorted((side * (hb - 0.30), side * (hb - 0.08)))
        for za, zb, rgb in ((0.68, 0.84, LAMP_AMBER), (0.84, 1.06, LAMP_TAIL), (1.06, 1.14, LAMP_BRAKE)):
            parts.add(_rect_x(xr - 0.012, y0, y1, za, zb, -1), rgb, LIGHT_MAT)
        parts.add(_rect_x(xf + 0.012, y0, y1, 0.66, 0.82, 1), LAMP_HEAD, LIGHT_MAT)
        parts.add(_rect_x(xf + 0.012, y0, y1, 0.84, 0.90, 1), LAMP_AMBER, LIGHT_MAT)
    _plate(parts, xr - 0.004, -1, 0.70, 0.81, PLATE_YELLOW if rng.uniform() < 0.4 else PLATE_WHITE, rng)
    _plate(parts, hl - 0.006, 1, 0.45, 0.56, PLATE_WHITE, rng)
    # wheels: single front tyres, twin rear ones, under dark arches
    for side in (-1, 1):
        for ax in (L.rear_axle_x, L.front_axle_x):
            _arch(parts, ax, side, hb + 0.012, r, r + 0.09, z0)
        _wheel_parts(parts, L.front_axle_x, side, hb + 0.04, 0.30, r, steel, True, dirt)
        _wheel_parts(parts, L.rear_axle_x, side, hb + 0.04, 0.28, r, steel, True, dirt)
        _wheel_parts(parts, L.rear_axle_x, side, hb + 0.04 - 0.31, 0.28, r, steel, False, dirt)
        # doors (front and middle, on the right) and panel lines
        for x in (L.front_axle_x + r + 0.25, L.rear_axle_x + r + 0.30):
            if side < 0:
                parts.add(_rect_y(-(hb + 0.006), x, x + 0.012, z0 + 0.05, belt - 0.05, -1), GAP, TRIM_MAT)
                parts.add(_rect_y(-(hb + 0.006), x + 1.1, x + 1.112, z0 + 0.05, belt - 0.05, -1), GAP, TRIM_MAT)
        # mirrors on arms at the front corners: the widest part, out to |Y| = hw
        y0, y1 = sorted((side * (hb - 0.02), side * hw))
        parts.add(_box_tris(xf - 0.45, xf - 0.33, y0, y1, 1.95, 2.45), TRIM_BLACK, TRIM_MAT)
        parts.add(_rect_x(xf - 0.456, *sorted((side * hb, side * (hw - 0.01))), 2.0, 2.4, -1), GLASS_TINT, GLASS_MAT)
    _contact_shadow(parts, hl, hw, (0.10, 0.06), (0.70, 0.45))
    return parts


def _detailed_rng(seed: int) -> np.random.Generator:
    return np.random.default_rng([int(seed) & 0xFFFFFFFF, 0x4835])


@functools.lru_cache(maxsize=512)
def _detailed_shape(length: float, width: float, dirt: float, seed: int, body: str | None = None):
    """Read-only triangles, normals, fixed colours, colour roles, grime strengths and materials of one detailed
    vehicle (built once per footprint, body type, dirt and seed)."""
    if body is None:
        build = _truck_parts if vehicle_layout(length, width).truck else _car_parts
        out = build(float(length), float(width), float(np.clip(dirt, 0.0, 1.0)), _detailed_rng(seed)).arrays()
    else:
        build = _bus_parts if body == "bus" else _truck_parts if body in ("box_truck", "artic") else _car_parts
        out = build(float(length), float(width), float(np.clip(dirt, 0.0, 1.0)), _detailed_rng(seed), body).arrays()
    for a in out:
        a.setflags(write=False)
    return out


def vehicle_faces_detailed(length: float, width: float, color: tuple[int, int, int], dirt: float = 0.0,
                           seed: int = 0, body: str | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A detailed vehicle of the realistic look in its model frame (X forward, Y left, Z up, m):
    triangles (F, 3, 3), unit face normals (F, 3), face colours (F, 3) (sRGB 0..255, float) and
    (F,) :class:`~harness.render.materials.Material` tags (int8).

    Cars and vans: body with bumper, tailgate step and shoulder, pillars between the side and rear
    windows, mirrors, wheel arches, tyres with recessed spoked rims, wrap-round tail and head lamps,
    plates with characters, grille and intakes, panel gaps, a dark sill/underbody, exhaust. Trucks:
    cab with windscreen and mirrors, box body or curtain-sider with rear doors (locking bars,
    hinges), chassis, under-run bar, light bar, mud flaps, twin rear tyres. Both: the dark ground
    under the body (:attr:`~harness.render.materials.Material.SHADOW`, 12-24 mm above Z = 0).
    ``dirt`` 0..1: grime on the lower body, higher and browner as it grows. ``seed`` picks the body
    style, lamp sizes, rims, plate colour and characters (the same seed, the same vehicle).

    ``body`` (:data:`harness.world.vehicles.BODY_TYPES`) builds that type instead of the footprint's: hatchback
    (short rear, raked hatch), saloon (boot), estate (long roof), SUV (taller, higher clearance and belt, an
    upright tailgate), pickup (cab and an open bed: its dark floor and liner ribs inside the rails), van (tall
    one-box), box truck (cab and box; a single rear axle up to 9 m), artic (tractor and semi-trailer as one rigid
    footprint: a tri-axle trailer group, the drive axle under its nose, a gap behind the cab, a roof fairing), bus
    (one box, a band of side windows between pillars, destination display, rear window over the engine grille).

    The mesh lies in the footprint box X in [-L/2, L/2], Y in [-W/2, W/2], Z in [0, vehicle_height]
    and touches all six of its faces: rear bumper (or the truck's rear posts) at -L/2, the front plate's
    characters (head lamps on a truck) at +L/2, mirrors (truck box sides) at +-W/2, roof (box rails)
    at the height, tyres on the ground at their axles.
    """
    triangles, normals, fixed, role, grime, material = _detailed_shape(float(length), float(width),
                                                                        float(dirt), int(seed), body)
    albedo = fixed.copy()
    paint = np.asarray(color, dtype=float)
    albedo[role == 1] = paint
    g = grime[role == 2][:, None]
    albedo[role == 2] = (1 - g) * paint + g * np.asarray(MUD, dtype=float)
    return triangles, normals, albedo, material
