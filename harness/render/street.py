"""An urban street's roadside in the realistic look (pure numpy): kerbs, the frontage, street furniture.

Used by :func:`harness.render.scenery.roadside_geometry` where ``road.street`` is set, with its
helpers (:func:`~harness.render.roadside.boxes`, ``frustums``, ``blobs``, ``Ground.place``) and in its
frames: road frame (x along the road, y right), W (X along, Y = -y left, Z up), object frame
(a along the road, b left, h up); m, sRGB 0..255. Distances ``d`` are measured outward from the clear
band's edge (the parking strip's outer edge, :func:`~harness.render.roadside.clear_band`):

- ``0 .. KERB_WIDTH_M``: the kerb (``KERB_HEIGHT_M`` high, swept along the road);
- ``.. frontage_d``: the pavement (a ground surface of :mod:`harness.render.road`), carrying lamp
  posts and sign poles near the kerb, street trees, cabinets near its outer edge;
- ``frontage_d ..``: garden walls, hedges and fences along the pavement's outer edge (a share of the
  frontage each, drive openings in front of houses), then houses set back 0-6 m: 2-4 storeys, window
  grids (framed dark glass quads just proud of the facade, some shuttered), a door, a plinth and a
  roof (``eaves``: ridge along the road; ``gable_front``: gable end to the street; ``hipped``; ``flat``).

Nothing stands on the band below :data:`OVERHEAD_M` (the parked cars' room); street-tree crowns and
lamp arms may reach over the parking strips above it, never over the carriageway. Every structure is
built facing +b (the road on the right side) and turned half a turn on the left side. Each kind has its
own generator from ``StreetLook.layout_seed``: same look, same geometry.
"""

from __future__ import annotations

import numpy as np

from harness.render.look import ROOF_FORMS, StreetLook
from harness.render.road import KERB_HEIGHT_M, KERB_WIDTH_M
from harness.render.roadside import (Batch, Ground, Layout, albedo_draw, blobs, boxes, frustums, plate_faces,
                                     stations, sweep, unit_sphere)
from harness.world.scenario import Road, Street

OVERHEAD_M = 3.2
"""Only tree crowns and lamp arms reach over a parking strip, and only above this height (m)."""
STOREY_M = (2.7, 3.1)
DEPTH_M = (8.0, 12.0)
"""House depth (m, across the road)."""
_QUAD = np.array([[0, 2, 1], [0, 3, 2]])            # corners (-a,-h), (a,-h), (a,h), (-a,h): facing +b
_ROOF_FACES = np.array([[0, 1, 2], [0, 2, 3], [5, 4, 3], [5, 3, 2], [1, 5, 2], [4, 0, 3], [0, 4, 5], [0, 5, 1]])
"""Roof faces over vertices (-A,-B,e), (A,-B,e), (A-i,0,t), (-A+i,0,t), (-A,B,e), (A,B,e): two slopes,
the two ends (gables, or hips when i > 0), the soffit underneath."""
FACADES = {
    "pastel": [(232, 222, 196), (236, 214, 150), (226, 180, 150), (210, 206, 198), (238, 236, 228),
               (222, 150, 80), (196, 210, 190)],
    "brick": [(150, 72, 52), (128, 62, 48), (168, 96, 70), (110, 58, 45), (225, 220, 210), (200, 190, 170)],
    "white": [(240, 238, 232), (228, 228, 224), (235, 230, 218), (215, 215, 212), (245, 242, 235)],
    "stone": [(200, 182, 150), (178, 170, 158), (196, 160, 110), (160, 140, 120), (215, 200, 175)],
}
ROOFS = np.array([[165, 68, 48], [130, 62, 45], [98, 66, 52], [72, 72, 78], [50, 52, 56]], float)
WALLS = np.array([[150, 78, 58], [190, 170, 140], [170, 168, 160], [215, 210, 200], [120, 115, 105]], float)
_HEDGE = ((44, 70, 34), (10, 14, 8))
_FOLIAGE = ((58, 88, 38), (14, 18, 10))
_BARK = ((88, 76, 62), (14, 12, 10))


def frontage_d(street: Street) -> float:
    """Distance (m) from the parking strip's outer edge to the pavement's outer edge."""
    return KERB_WIDTH_M + street.pavement_m


def _facing(local: np.ndarray, side: np.ndarray) -> np.ndarray:
    """Object-frame points (n, V, 3) built facing +b turned half a turn where ``side`` > 0 (left)."""
    flip = np.where(np.asarray(side) > 0, -1.0, 1.0)[:, None]
    return np.stack([local[..., 0] * flip, local[..., 1] * flip, local[..., 2]], -1)


def _quads(a: np.ndarray, b: np.ndarray, h: np.ndarray, half_a: np.ndarray, half_h: np.ndarray) -> np.ndarray:
    """(n, 4, 3) corners of upright quads facing +b, centred at (a, b, h), for :data:`_QUAD`."""
    da = np.stack([-half_a, half_a, half_a, -half_a], 1)
    dh = np.stack([-half_h, -half_h, half_h, half_h], 1)
    return np.stack([a[:, None] + da, np.repeat(b[:, None], 4, 1), h[:, None] + dh], -1)


class _Out:
    """Batches and shadow-casting point sets collected by the generators."""

    def __init__(self, ground: Ground) -> None:
        self.ground, self.batches, self.parts = ground, [], []

    def add(self, local, faces, x, yl, side, albedo, kind: str, shadow: bool = True) -> None:
        v = self.ground.place(_facing(local, side), x, yl)
        self.batches.append(Batch(v, faces, albedo, kind))
        if shadow:
            self.parts += list(v)


# --------------------------------------------------------------------------- kerbs
def _kerbs(out: _Out, lay: Layout, rng: np.random.Generator, look: StreetLook) -> None:
    xs = stations(out.ground, lay.x0, lay.x1)
    for side in (+1, -1):
        d = np.array([0.0, 0.0, 0.02, KERB_WIDTH_M, KERB_WIDTH_M])
        h = np.array([-0.05, KERB_HEIGHT_M - 0.02, KERB_HEIGHT_M, KERB_HEIGHT_M, -0.05])
        verts, faces = sweep(out.ground, xs, np.stack([lay.yl(np.full(5, side), d), h], -1), closed=False)
        n = len(verts)
        alb = np.broadcast_to(np.asarray(look.kerb_srgb, float) * (1 + rng.uniform(-0.06, 0.06, (n, 1, 1))),
                              (n, len(faces), 3))
        out.batches.append(Batch(verts, faces, alb, "kerb"))


# --------------------------------------------------------------------------- plots
def _plots(rng: np.random.Generator, lay: Layout, look: StreetLook) -> tuple[np.ndarray, ...]:
    """Plots along both sides: start and end x (m), side (+1 left, -1 right), whether a house stands there."""
    out = []
    for side in (+1, -1):
        n = int((lay.x1 - lay.x0) / 6.0) + 2
        house = rng.uniform(size=n) < look.house_share
        width = np.where(house, rng.uniform(*look.house_width_m, n), rng.uniform(5, 18, n))
        gap = np.where(house, rng.exponential(look.house_gap_m, n) + 0.8, 0.0)
        start = lay.x0 + rng.uniform(-10, 0) + np.r_[0.0, np.cumsum(width + gap)[:-1]]
        keep = start < lay.x1
        out.append((start[keep], (start + width)[keep], np.full(keep.sum(), side), house[keep], gap[keep]))
    return tuple(np.concatenate(c) for c in zip(*out))


# --------------------------------------------------------------------------- houses
def _gable(a, b, e, t, inset) -> np.ndarray:
    """(n, 6, 3) roof vertices, ridge along a (see :data:`_ROOF_FACES`)."""
    z = np.zeros_like(a)
    return np.stack([np.stack(c, -1) for c in ((-a, -b, e), (a, -b, e), (a - inset, z, t), (-a + inset, z, t),
                                                (-a, b, e), (a, b, e))], 1)


def _roofs(out: _Out, rng, x, yl, side, w, depth, wall_h, form, wall_c) -> None:
    n = len(x)
    colour = ROOFS[rng.integers(0, len(ROOFS), n)] * rng.uniform(0.9, 1.1, (n, 1))
    ov = rng.uniform(0.25, 0.5, n)
    pitch = np.tan(np.radians(rng.uniform(30, 48, n)))
    a, b, e = w / 2 + ov, depth / 2 + ov, wall_h - 0.1
    for f in ("eaves", "gable_front", "hipped"):
        s = form == f
        if not s.any():
            continue
        if f == "gable_front":   # ridge across the road: built along a, then a and b swapped (winding reversed)
            v = _gable(b[s], a[s], e[s], e[s] + a[s] * pitch[s], 0 * a[s])[..., [1, 0, 2]]
            faces = _ROOF_FACES[:, ::-1]
        else:
            inset = np.minimum(b[s], a[s] - 0.2) if f == "hipped" else 0 * a[s]
            v = _gable(a[s], b[s], e[s], e[s] + b[s] * pitch[s] * (0.8 if f == "hipped" else 1.0), inset)
            faces = _ROOF_FACES
        alb = np.repeat(colour[s][:, None], 8, 1) * (1 + rng.uniform(-0.04, 0.04, (s.sum(), 8, 1)))
        if f != "hipped":                                    # gable ends in the facade's colour
            alb[:, 4:6] = wall_c[s][:, None]
        alb[:, 6:] = wall_c[s][:, None] * 0.8
        out.add(v, faces, x[s], yl[s], side[s], alb, "house")
    s = form == "flat"
    if s.any():
        k = int(s.sum())
        v, f = boxes(np.stack([0 * a[s], 0 * a[s], wall_h[s] + 0.15], -1),
                     np.stack([w[s] + 0.3, depth[s] + 0.3, np.full(k, 0.4)], -1), bottom=True)
        out.add(v, f, x[s], yl[s], side[s], albedo_draw(rng, (150, 148, 142), (20, 20, 20), k, len(f), 0.03), "house")


def _houses(out: _Out, lay: Layout, rng: np.random.Generator, look: StreetLook, x0, x1, side, front: float) -> None:
    n = len(x0)
    if n == 0:
        return
    w = x1 - x0
    depth = rng.uniform(*DEPTH_M, n)
    storeys = rng.integers(look.storeys[0], look.storeys[1] + 1, n)
    storey_h = rng.uniform(*STOREY_M, n)
    plinth = rng.uniform(0.2, 0.7, n)
    wall_h = plinth + storeys * storey_h
    x, yl = (x0 + x1) / 2, lay.yl(side, front + rng.uniform(*look.setback_m, n) + depth / 2)
    zero = np.zeros(n)
    palette = np.asarray(FACADES[look.facade_palette], float)
    wall_c = palette[rng.integers(0, len(palette), n)] * rng.uniform(0.9, 1.06, (n, 1))
    v, f = boxes(np.stack([zero, zero, (wall_h - 0.5) / 2], -1), np.stack([w, depth, wall_h + 0.5], -1))
    alb = np.repeat(wall_c[:, None], len(f), 1) * (1 + rng.uniform(-0.03, 0.03, (n, len(f), 1)))
    out.add(v, f, x, yl, side, alb, "house")
    v, f = boxes(np.stack([zero, zero, (plinth - 0.5) / 2], -1), np.stack([w + 0.06, depth + 0.06, plinth + 0.5], -1))
    out.add(v, f, x, yl, side, np.repeat((wall_c * 0.62)[:, None], len(f), 1), "house", shadow=False)
    forms = ROOF_FORMS["train" if look.roof_form in ROOF_FORMS["train"] else "heldout"]
    other = forms[1 - forms.index(look.roof_form)]
    form = np.where(rng.uniform(size=n) < look.roof_mix, other, look.roof_form)
    _roofs(out, rng, x, yl, side, w, depth, wall_h, form, wall_c)
    _windows(out, rng, x, yl, side, w, depth, storeys, storey_h, plinth)


def _windows(out: _Out, rng, x, yl, side, w, depth, storeys, storey_h, plinth) -> None:
    """Window grids on the road-facing facades (a door in place of one ground-floor window)."""
    n = len(x)
    pitch_w = rng.uniform(2.2, 3.3, n)
    cols = np.maximum(1, np.floor((w - 0.8) / pitch_w)).astype(int)
    pitch_w = (w - 0.8) / cols
    win_w = np.minimum(0.6 * pitch_w, rng.uniform(0.9, 1.5, n))
    win_h = rng.uniform(1.2, 1.6, n)
    door_col = rng.integers(0, cols)
    frame_c = np.where(rng.uniform(size=(n, 1)) < 0.7, [[225, 224, 218]], [[70, 60, 52]])
    house = np.repeat(np.arange(n), cols * storeys)
    j = np.arange(len(house)) - np.repeat(np.r_[0, np.cumsum(cols * storeys)[:-1]], cols * storeys)
    row, col = j // cols[house], j % cols[house]
    door = (row == 0) & (col == door_col[house])
    a = -w[house] / 2 + 0.4 + (col + 0.5) * pitch_w[house]
    b = depth[house] / 2
    h = plinth[house] + row * storey_h[house] + 0.9 + win_h[house] / 2
    hw, hh = win_w[house] / 2, win_h[house] / 2
    win, dr = ~door, door
    m = int(win.sum())
    glass = np.where(rng.uniform(size=(m, 1)) < 0.15, rng.uniform(120, 200, (m, 1)) * [[1, 0.98, 0.94]],
                     rng.uniform(28, 80, (m, 1)) * [[0.9, 1.0, 1.15]])
    hs, sd = house[win], side[house][win]
    out.add(_quads(a[win], b[win] + 0.02, h[win], hw[win] + 0.08, hh[win] + 0.08), _QUAD, x[hs], yl[hs], sd,
            np.repeat(frame_c[hs][:, None], 2, 1), "facade", shadow=False)
    out.add(_quads(a[win], b[win] + 0.05, h[win], hw[win], hh[win]), _QUAD, x[hs], yl[hs], sd,
            np.repeat(glass[:, None], 2, 1), "facade", shadow=False)
    hd = house[dr]
    k = len(hd)
    door_h = rng.uniform(2.05, 2.3, k)
    out.add(_quads(a[dr], b[dr] + 0.04, plinth[hd] - 0.1 + door_h / 2, np.full(k, 0.55), door_h / 2), _QUAD,
            x[hd], yl[hd], side[hd], albedo_draw(rng, (90, 70, 55), (40, 30, 25), k, 2), "facade", shadow=False)


# --------------------------------------------------------------------------- boundaries
def _segments(rng, x0, x1, side, house) -> tuple[np.ndarray, ...]:
    """Boundary segments of the plots (a drive opening in front of most houses): start, end, side."""
    length = x1 - x0
    gate = np.where(house & (rng.uniform(size=len(x0)) < 0.8), rng.uniform(1.0, 3.5, len(x0)), 0.0)
    gate = np.minimum(gate, 0.8 * length)
    g0 = x0 + rng.uniform(0, 1, len(x0)) * (length - gate)
    a, b = np.r_[x0, g0 + gate], np.r_[g0, x1]
    s = np.r_[side, side]
    keep = b - a > 0.4
    return a[keep], b[keep], s[keep]


def _boundaries(out: _Out, lay, rng, look: StreetLook, x0, x1, side, house, front: float) -> None:
    a, b, s = _segments(rng, x0, x1, side, house)
    u = rng.uniform(size=len(a))
    cut = np.cumsum([look.wall_share, look.hedge_share, look.fence_share])
    kind = np.searchsorted(cut, u)                                    # 0 wall, 1 hedge, 2 fence, 3 open
    _walls(out, lay, rng, a[kind == 0], b[kind == 0], s[kind == 0], front)
    _hedges(out, lay, rng, a[kind == 1], b[kind == 1], s[kind == 1], front)
    _fences(out, lay, rng, a[kind == 2], b[kind == 2], s[kind == 2], front)


def _walls(out: _Out, lay, rng, a, b, side, front) -> None:
    n = len(a)
    if n == 0:
        return
    length, zero = b - a, np.zeros(n)
    h = np.clip(rng.lognormal(np.log(0.9), 0.4, n), 0.5, 2.0)
    t = rng.uniform(0.2, 0.35, n)
    x, yl = (a + b) / 2, lay.yl(side, front + 0.05 + t / 2)
    colour = WALLS[rng.integers(0, len(WALLS), n)] * rng.uniform(0.9, 1.08, (n, 1))
    v, f = boxes(np.stack([zero, zero, (h - 0.3) / 2], -1), np.stack([length, t, h + 0.3], -1))
    out.add(v, f, x, yl, side, np.repeat(colour[:, None], len(f), 1) * (1 + rng.uniform(-0.04, 0.04, (n, len(f), 1))),
            "boundary")
    v, f = boxes(np.stack([zero, zero, h + 0.03], -1), np.stack([length + 0.04, t + 0.06, zero + 0.06], -1),
                 bottom=True)
    out.add(v, f, x, yl, side, np.repeat((np.minimum(colour * 1.15, 235))[:, None], len(f), 1), "boundary",
            shadow=False)


def _boxy_blobs(rng, centre: np.ndarray, radii: np.ndarray, jitter: float) -> tuple[np.ndarray, np.ndarray]:
    """Icospheres pushed towards their bounding boxes (|v| ** 0.35 per axis), lumpy by ``jitter``: hedge chunks."""
    v, f = unit_sphere(1)
    p = np.sign(v) * np.abs(v) ** 0.35
    p = p[None] * (1 + rng.uniform(-jitter, jitter, (len(centre), len(v), 1)))
    return centre[:, None, :] + radii[:, None, :] * p, f


def _hedges(out: _Out, lay, rng, a, b, side, front) -> None:
    if len(a) == 0:
        return
    h_seg = rng.uniform(1.0, 2.5, len(a))
    t_seg = rng.uniform(0.6, 1.2, len(a))
    k = np.ceil((b - a) / 3.0).astype(int)
    seg = np.repeat(np.arange(len(a)), k)
    i = np.arange(len(seg)) - np.repeat(np.r_[0, np.cumsum(k)[:-1]], k)
    step = (b - a)[seg] / k[seg]
    x = a[seg] + (i + 0.5) * step
    n = len(x)
    h = h_seg[seg] * rng.uniform(0.9, 1.1, n)
    t = t_seg[seg]
    c = np.stack([np.zeros(n), np.zeros(n), h / 2 - 0.05], -1)
    r = np.stack([step * 0.58, t / 2, h / 2], -1)
    v, f = _boxy_blobs(rng, c, r, 0.08)
    tint = np.where(rng.uniform(size=(len(a), 1)) < 0.3, [[1.25, 1.15, 0.9]], [[1.0, 1.0, 1.0]])[seg]
    alb = albedo_draw(rng, *_HEDGE, n, len(f), 0.22) * tint[:, None]
    out.add(v, f, x, lay.yl(side[seg], front + 0.05 + t / 2), side[seg], alb, "boundary")


def _fences(out: _Out, lay, rng, a, b, side, front) -> None:
    n = len(a)
    if n == 0:
        return
    length, zero = b - a, np.zeros(n)
    h = rng.uniform(0.9, 1.7, n)
    x, yl = (a + b) / 2, lay.yl(side, front + 0.1)
    bars = rng.uniform(size=n) < 0.6
    metal = np.where(rng.uniform(size=(n, 1)) < 0.6, [[52, 54, 56]], [[60, 84, 62]])
    wood = np.array([[120, 88, 60]]) * rng.uniform(0.7, 1.2, (n, 1))
    colour = np.where(bars[:, None], metal, wood)
    # the top rail of a bar fence (and its bottom rail), the panel of a board fence
    v, f = boxes(np.stack([zero, zero, np.where(bars, h - 0.05, h / 2)], -1),
                 np.stack([length, zero + 0.04, np.where(bars, 0.05, h - 0.1)], -1), bottom=True)
    alb = np.repeat(colour[:, None], len(f), 1) * (1 + rng.uniform(-0.08, 0.08, (n, len(f), 1)))
    out.add(v, f, x, yl, side, alb, "boundary")
    if bars.any():
        v, f = boxes(np.stack([zero, zero, zero + 0.15], -1)[bars],
                     np.stack([length, zero + 0.04, zero + 0.05], -1)[bars],
                     bottom=True)
        out.add(v, f, x[bars], yl[bars], side[bars], alb[bars], "boundary", shadow=False)
    # posts every ~2.5 m
    kp = np.ceil(length / 2.5).astype(int) + 1
    seg = np.repeat(np.arange(n), kp)
    i = np.arange(len(seg)) - np.repeat(np.r_[0, np.cumsum(kp)[:-1]], kp)
    px = a[seg] + i * length[seg] / (kp[seg] - 1)
    m = len(px)
    v, f = boxes(np.stack([np.zeros(m), np.zeros(m), (h[seg] - 0.3) / 2 + 0.05], -1),
                 np.stack([np.full(m, 0.07), np.full(m, 0.07), h[seg] + 0.4], -1))
    out.add(v, f, px, lay.yl(side[seg], front + 0.1), side[seg], np.repeat(colour[seg][:, None], len(f), 1) * 0.9,
            "boundary")
    # vertical bars of the metal fences, 0.13 m apart (quads facing the road, no shadows)
    kb = np.where(bars, np.floor(length / 0.13), 0).astype(int)
    seg = np.repeat(np.arange(n), kb)
    i = np.arange(len(seg)) - np.repeat(np.r_[0, np.cumsum(kb)[:-1]], kb)
    bx = a[seg] + (i + 0.5) * length[seg] / np.maximum(kb[seg], 1)
    m = len(bx)
    if m:
        q = _quads(np.zeros(m), np.full(m, 0.025), h[seg] / 2, np.full(m, 0.012), h[seg] / 2 - 0.02)
        out.add(q, _QUAD, bx, lay.yl(side[seg], front + 0.1), side[seg], np.repeat(colour[seg][:, None], 2, 1),
                "boundary", shadow=False)


# --------------------------------------------------------------------------- trees and furniture
def _street_trees(out: _Out, lay, rng, look: StreetLook, road: Road, front: float) -> None:
    """Street trees in the pavement near the kerb, and garden trees just behind the boundary."""
    xs, sides = [], []
    for side in (+1, -1):
        if look.tree_density <= 0:
            continue
        spacing = 100.0 / look.tree_density
        x = np.arange(lay.x0 + rng.uniform(0, spacing), lay.x1, spacing) + rng.normal(0, 0.15 * spacing)
        x = x[rng.uniform(size=len(x)) < 0.8]
        xs.append(x)
        sides.append(np.full(len(x), side))
    if not xs:
        return
    x, side = np.concatenate(xs), np.concatenate(sides)
    n = len(x)
    if n == 0:
        return
    garden = rng.uniform(size=n) < 0.5
    pave = front - KERB_WIDTH_M
    d = np.where(garden, front + rng.uniform(1.0, 4.0, n),
                 KERB_WIDTH_M + np.minimum(rng.uniform(0.5, 0.9, n), pave / 2))
    height = np.where(garden, rng.uniform(6, 16, n), rng.uniform(6, 12, n))
    base = np.maximum(OVERHEAD_M + 0.3, height * rng.uniform(0.3, 0.45, n))
    reach_max = (d + road.shoulder_width_m - 0.3) / 1.5                  # crowns never over the carriageway
    rc = np.minimum(height * rng.uniform(0.22, 0.32, n), reach_max)
    half_z = (height - base) / 2
    zero = np.zeros(n)
    yl = lay.yl(side, d)
    v, f = frustums(np.stack([zero, zero, zero - 0.4], -1), np.stack([zero, zero, base + half_z], -1),
                    0.012 * height + 0.07, 0.008 * height + 0.05, 6, top=False)
    out.add(v, f, x, yl, side, albedo_draw(rng, *_BARK, n, len(f), 0.05), "street_tree")
    tint = rng.uniform(0.8, 1.15, (n, 1, 1))
    for k in range(3):
        off = rng.uniform([-0.35, -0.35, -0.25], [0.35, 0.35, 0.25], (n, 3)) * np.stack([rc, rc, half_z], -1)
        c = np.stack([zero, zero, base + half_z], -1) + off
        r = rng.uniform(0.6, 0.75, (n, 1)) * np.stack([rc, rc, half_z], -1)
        r[:, 2] = np.minimum(r[:, 2], (c[:, 2] - OVERHEAD_M - 0.05) / 1.13)  # crown bottom above OVERHEAD_M
        v, f = blobs(rng, c, r, 1, 0.12)
        out.add(v, f, x, yl, side, albedo_draw(rng, *_FOLIAGE, n, len(f), 0.08) * tint, "street_tree")


def _lamps(out: _Out, lay, rng, look: StreetLook, road: Road) -> None:
    s = look.lamp_spacing_m
    if s <= 0:
        return
    which = rng.choice(["right", "left", "both"])
    xs, sides = [], []
    for side, name in ((-1, "right"), (+1, "left")):
        if which in (name, "both"):
            x = np.arange(lay.x0 + rng.uniform(0, s), lay.x1, s)
            xs.append(x)
            sides.append(np.full(len(x), side))
    x, side = np.concatenate(xs), np.concatenate(sides)
    n = len(x)
    zero, one = np.zeros(n), np.ones(n)
    height = np.full(n, rng.uniform(5.5, 8.0))
    arm = min(rng.uniform(0.6, 1.4), road.shoulder_width_m - 0.3)
    yl = lay.yl(side, np.full(n, KERB_WIDTH_M + 0.35))
    grey = (95, 98, 102), (20, 20, 20)
    v, f = frustums(np.stack([zero, zero, zero - 0.3], -1), np.stack([zero, zero, height], -1),
                    one * 0.08, one * 0.05, 8)
    out.add(v, f, x, yl, side, albedo_draw(rng, *grey, n, len(f)), "furniture")
    v, f = boxes(np.stack([zero, zero + arm / 2, height - 0.1], -1), np.tile([[0.06, arm + 0.1, 0.06]], (n, 1)),
                 bottom=True)
    out.add(v, f, x, yl, side, albedo_draw(rng, *grey, n, len(f)), "furniture")
    v, f = boxes(np.stack([zero, zero + arm, height - 0.2], -1), np.tile([[0.45, 0.3, 0.14]], (n, 1)), bottom=True)
    out.add(v, f, x, yl, side, albedo_draw(rng, (200, 200, 195), (10, 10, 10), n, len(f)), "furniture")


_PLATES = np.array([[30, 70, 160], [190, 30, 35], [232, 232, 228], [230, 190, 40]], float)


def _scattered(lay, rng, per_100m: float) -> tuple[np.ndarray, np.ndarray]:
    """Positions along the road (m) and sides (+1 right, -1 left) of objects scattered uniformly, a Poisson
    number ``per_100m`` per 100 m on each side (right first)."""
    xs, sides = [], []
    for side in (+1, -1):
        n = rng.poisson(per_100m * (lay.x1 - lay.x0) / 100.0)
        xs.append(rng.uniform(lay.x0, lay.x1, n))
        sides.append(np.full(n, side))
    return np.concatenate(xs), np.concatenate(sides)


def _signs(out: _Out, lay, rng, look: StreetLook, front: float) -> None:
    """Sign poles near the kerb, their plates facing the side's oncoming traffic; and street cabinets."""
    x, side = _scattered(lay, rng, look.sign_density)
    n = len(x)
    if n:
        zero = np.zeros(n)
        yl = lay.yl(side, np.full(n, KERB_WIDTH_M + 0.4))
        top = rng.uniform(2.4, 3.0, n)
        v, f = frustums(np.stack([zero, zero, zero - 0.3], -1), np.stack([zero, zero, top], -1), zero + 0.035,
                        zero + 0.035, 6)
        out.add(v, f, x, yl, side, albedo_draw(rng, (150, 150, 152), (10, 10, 10), n, len(f)), "furniture")
        size = rng.uniform(0.5, 0.75, n)
        v, f = boxes(np.stack([zero - 0.05, zero, top - size / 2], -1), np.stack([zero + 0.03, size, size], -1),
                     bottom=True)
        out.add(v, f, x, yl, side, plate_faces(rng, n, f, v, _PLATES[rng.integers(0, len(_PLATES), n)]), "furniture")
    x, side = _scattered(lay, rng, look.cabinet_density)
    n = len(x)
    if n:
        zero = np.zeros(n)
        w, t, h = rng.uniform(0.5, 1.3, n), rng.uniform(0.3, 0.5, n), rng.uniform(0.9, 1.5, n)
        yl = lay.yl(side, np.maximum(front - t / 2 - 0.05, KERB_WIDTH_M + 0.3 + t / 2))
        v, f = boxes(np.stack([zero, zero, h / 2 - 0.1], -1), np.stack([w, t, h + 0.2], -1))
        colour = np.array([[150, 150, 145], [95, 115, 95], [200, 195, 180]], float)[rng.integers(0, 3, n)]
        alb = np.repeat(colour[:, None], len(f), 1) * (1 + rng.uniform(-0.05, 0.05, (n, len(f), 1)))
        out.add(v, f, x, yl, side, alb, "furniture")


# --------------------------------------------------------------------------- the whole
def street_geometry(ground: Ground, road: Road, lay: Layout,
                    look: StreetLook) -> tuple[list[Batch], list[np.ndarray]]:
    """The kerbs, frontage and street furniture of ``road`` (``road.street`` set; ``lay`` the clear
    band's layout) for ``look``: W batches and the (V, 3) W point sets that cast shadows."""
    def gen(tag: int) -> np.random.Generator:
        return np.random.default_rng([int(look.layout_seed) & 0xFFFFFFFF, 0x57EE7, tag])

    out = _Out(ground)
    front = frontage_d(road.street)
    _kerbs(out, lay, gen(1), look)
    x0, x1, side, house, _ = _plots(gen(2), lay, look)
    _houses(out, lay, gen(3), look, x0[house], x1[house], side[house], front)
    _boundaries(out, lay, gen(4), look, x0, x1, side, house, front)
    _street_trees(out, lay, gen(5), look, road, front)
    _lamps(out, lay, gen(6), look, road)
    _signs(out, lay, gen(7), look, front)
    return out.batches, out.parts
