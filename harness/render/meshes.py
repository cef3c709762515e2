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
"""

from __future__ import annotations

import functools

import numpy as np
import trimesh

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


def vehicle_trimesh(length: float, width: float, color: tuple[int, int, int]) -> trimesh.Trimesh:
    """One merged mesh (face colours) of a vehicle in its model frame."""
    return trimesh.util.concatenate(_vehicle_parts(length, width, color))


def vehicle_faces(length: float, width: float,
                  color: tuple[int, int, int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`vehicle_trimesh`'s triangles (F, 3, 3), face normals (F, 3) and face colours (F, 3) (0..255, float),
    the shape built once per footprint (the convex hulls are the cost) and painted per call."""
    triangles, normals, colors, painted = _vehicle_shape(length, width)
    colors = colors.copy()
    colors[painted] = color
    return triangles, normals, colors


@functools.lru_cache(maxsize=256)
def _vehicle_shape(length: float, width: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Read-only triangles, face normals, face colours (painted faces unset) and painted-face mask of one footprint."""
    parts = _vehicle_parts(length, width, None)
    tm = trimesh.util.concatenate(parts)
    painted = np.repeat([bool(p.metadata.get("painted")) for p in parts], [len(p.faces) for p in parts])
    out = (tm.vertices[tm.faces], tm.face_normals, tm.visual.face_colors[:, :3].astype(float), painted)
    for a in out:
        a.setflags(write=False)
    return out


def _vehicle_parts(length: float, width: float, color: tuple[int, int, int] | None) -> list[trimesh.Trimesh]:
    """The parts of :func:`vehicle_trimesh`; ``color`` None leaves the painted ones uncoloured (marked ``painted``)."""
    L = vehicle_layout(length, width)
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
        axles = [L.rear_axle_x, L.rear_axle_x + 1.3, L.front_axle_x]
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
