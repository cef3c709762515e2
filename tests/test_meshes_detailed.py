"""Detailed vehicle meshes of the realistic look (harness.render.meshes.vehicle_faces_detailed): the simple
meshes are byte-identical to before, the detailed ones fill exactly the footprint box the ground truth
uses, stand on their tyres, carry a material tag per face, face outwards where they are seen, and show
the dark band under the body that a camera behind them sees."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest
import trimesh

from harness.render.look import SkyLook, SunLook
from harness.render.materials import Material, shade_matte, shade_realistic, srgb_to_linear
from harness.render.meshes import (CAR_MAX_TRIANGLES, TRUCK_MAX_TRIANGLES, vehicle_faces, vehicle_faces_detailed,
                                   vehicle_trimesh)
from harness.world.vehicles import vehicle_height, vehicle_layout

# sha256 of the simple meshes (triangles, normals, colours of vehicle_faces; vertices, faces, face colours of
# vehicle_trimesh) recorded from the implementation before the detailed vehicles were added.
SIMPLE_HASHES = {
    (4.5, 1.8, (170, 25, 30)): ("befd4a8c6913bb08ddfe561c68c552f091382cc0aad47953d60e7911304aceff",
                                "2b23509cec7639337577fc053ae73776053b2a043e9db26e782b71be05a787bd"),
    (3.8, 1.7, (25, 55, 130)): ("c86e26f9a05eddba80df47902af6baa3c9e733bce167e2688d08582ab516da2a",
                                "006d0fcbfc55537cc2b288942c13272e18f6fba08373a5703b7f0c48b14eb331"),
    (5.5, 2.0, (235, 235, 232)): ("a90161a5ce989fbfed599d61f28e9c6e161f7330edb50f05c15e81fde35a83a0",
                                  "404dc28b2981dc2f40dfd74d21cdae57c8fdb195ba54789ca05906f709f52d46"),
    (6.0, 2.0, (95, 98, 104)): ("da66a0c5e3638bb956769d5448844cdcedcce6bb4f8c2040518c1f4b809210e4",
                                "126cb19997329825dea847a474f690a46969e6c27d9847363ce30c72915a3d35"),
    (7.5, 2.4, (225, 180, 30)): ("05c99895488e419fae847824e7e45bc694f1ebc5c90072fe317d58f1e347d7b2",
                                 "199b080d72d6a3539af1242f7c01162bd9f961b64429abfcfe1c3f337742a54d"),
    (12.0, 2.5, (30, 80, 50)): ("de9d5260e5b09928434a36a71581322c06edd456ba01667fafa290436f0d45a0",
                                "bb82e296d6c74bf76837da283f6a63dafaa65db2b26f89ae9229645c54726592"),
    (16.0, 2.55, (200, 185, 150)): ("d7e012ea08f01668f05ddfdce03021702c28330d06dcda82e1eeee3b4a517167",
                                    "eb03c7c308ca5e88acf42d6fe9b1639c7086a2de1430e39f0587f1fcfa0c00f2"),
}

CARS = [(3.8, 1.7), (4.2, 1.75), (4.6, 1.85), (5.0, 2.0), (5.5, 2.0)]
VANS = [(5.8, 2.0), (6.5, 2.1), (7.0, 2.2)]
TRUCKS = [(7.5, 2.4), (10.0, 2.5), (12.0, 2.5), (16.0, 2.55)]
FOOTPRINTS = CARS + VANS + TRUCKS
RED = (170, 25, 30)
WHITE = (235, 235, 232)


def _faces_hash(t, n, a) -> str:
    h = hashlib.sha256()
    for arr in (t, n, a):
        h.update(str(arr.dtype).encode())
        h.update(str(arr.shape).encode())
        h.update(np.ascontiguousarray(arr).tobytes())
    return h.hexdigest()


@pytest.mark.parametrize("key", list(SIMPLE_HASHES))
def test_simple_meshes_are_byte_identical_to_before(key):
    length, width, color = key
    want_faces, want_trimesh = SIMPLE_HASHES[key]
    assert _faces_hash(*vehicle_faces(length, width, color)) == want_faces
    assert _faces_hash(*vehicle_faces(length, width, color, detailed=False, dirt=0.7, seed=9)) == want_faces
    tm = vehicle_trimesh(length, width, color)
    h = hashlib.sha256()
    for arr in (tm.vertices, tm.faces, tm.visual.face_colors):
        h.update(arr.tobytes())
    assert h.hexdigest() == want_trimesh


def _trimesh(triangles: np.ndarray) -> trimesh.Trimesh:
    return trimesh.Trimesh(triangles.reshape(-1, 3), np.arange(3 * len(triangles)).reshape(-1, 3), process=False)


@pytest.mark.parametrize("length,width", FOOTPRINTS)
@pytest.mark.parametrize("seed,dirt", [(0, 0.0), (1, 0.5), (2, 1.0)])
def test_detailed_mesh_fills_the_footprint_box_exactly(length, width, seed, dirt):
    """Inside X in [-L/2, L/2], Y in [-W/2, W/2], Z in [0, height] and touching all six faces (trimesh bounds)."""
    t, n, a, m = vehicle_faces_detailed(length, width, RED, dirt, seed)
    want = np.array([[-length / 2, -width / 2, 0.0], [length / 2, width / 2, vehicle_height(length, width)]])
    np.testing.assert_allclose(_trimesh(t).bounds, want, rtol=0, atol=1e-9)
    assert len(t) <= (TRUCK_MAX_TRIANGLES if vehicle_layout(length, width).truck else CAR_MAX_TRIANGLES)
    assert CAR_MAX_TRIANGLES <= 2500 and TRUCK_MAX_TRIANGLES <= 4000


@pytest.mark.parametrize("length,width", FOOTPRINTS)
def test_arrays_are_consistent_and_tagged(length, width):
    t, n, a, m = vehicle_faces_detailed(length, width, RED, 0.4, 3)
    assert t.shape == (len(t), 3, 3) and n.shape == a.shape == (len(t), 3) and m.shape == (len(t),)
    assert np.issubdtype(m.dtype, np.integer) and set(np.unique(m)) <= {int(v) for v in Material}
    cross = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    area = np.linalg.norm(cross, axis=1)
    assert area.min() > 1e-10                                                   # no degenerate faces
    np.testing.assert_allclose(n, cross / area[:, None], atol=1e-12)            # normals follow the winding
    assert ((a >= 0) & (a <= 255)).all()
    need = {Material.PAINT, Material.GLASS, Material.TYRE, Material.RIM, Material.LIGHT, Material.PLATE,
            Material.TRIM, Material.DIRT, Material.SHADOW}
    assert need <= set(Material(v) for v in np.unique(m))
    assert not (m == Material.MATTE).any()                                      # every face says what it is


def test_detailed_is_deterministic_and_the_seed_varies_it():
    a = vehicle_faces_detailed(4.6, 1.85, RED, 0.3, 5)
    b = vehicle_faces_detailed(4.6, 1.85, RED, 0.3, 5)
    for x, y in zip(a, b):
        assert x.tobytes() == y.tobytes()
    others = [vehicle_faces_detailed(4.6, 1.85, RED, 0.3, s) for s in range(6)]
    assert len({o[0].tobytes() for o in others}) > 1
    # the 3-tuple path is the same detailed vehicle without its tags
    for x, y in zip(vehicle_faces(4.6, 1.85, RED, detailed=True, dirt=0.3, seed=5), a[:3]):
        assert x.tobytes() == y.tobytes()


def test_paint_is_applied_per_call():
    t1, _, a1, m1 = vehicle_faces_detailed(4.6, 1.85, RED, 0.0, 1)
    _, _, a2, _ = vehicle_faces_detailed(4.6, 1.85, WHITE, 0.0, 1)
    paint = m1 == Material.PAINT
    assert (a1[paint] == RED).all(1).mean() > 0.9 and (a2[paint] == WHITE).all(1).mean() > 0.9
    fixed = (m1 == Material.TYRE) | (m1 == Material.GLASS) | (m1 == Material.PLATE)
    np.testing.assert_array_equal(a1[fixed], a2[fixed])


@pytest.mark.parametrize("length,width", FOOTPRINTS)
def test_wheels_touch_the_ground_at_their_axles(length, width):
    L = vehicle_layout(length, width)
    t, _, _, m = vehicle_faces_detailed(length, width, RED, 0.0, 0)
    tyre = t[m == Material.TYRE].reshape(-1, 3)
    assert tyre[:, 2].min() == 0.0
    others = t[(m != Material.TYRE)].reshape(-1, 3)
    assert others[:, 2].min() > 0.0                                             # only the tyres touch the ground
    axles = [L.rear_axle_x, L.front_axle_x] + ([L.rear_axle_x + 1.3] if L.truck else [])
    on_ground = tyre[tyre[:, 2] == 0.0]
    for ax in axles:
        for side in (-1, 1):
            hit = on_ground[(np.abs(on_ground[:, 0] - ax) < 1e-9) & (np.sign(on_ground[:, 1]) == side)]
            assert len(hit), (ax, side)
            assert np.abs(hit[:, 1]).max() <= width / 2


@pytest.mark.parametrize("length,width", CARS + VANS)
def test_only_the_mirrors_reach_the_full_width(length, width):
    """The body is inset so that the mirrors, above the belt line, are the widest part (exactly W/2)."""
    L = vehicle_layout(length, width)
    t, _, _, m = vehicle_faces_detailed(length, width, RED, 0.0, 0)
    v = t.reshape(-1, 3)
    wide = v[np.abs(v[:, 1]) > width / 2 - 0.03]
    assert len(wide) and (wide[:, 2] > L.belt).all() and (wide[:, 2] < L.belt + 0.45).all()
    assert np.isclose(np.abs(wide[:, 1]).max(), width / 2, atol=1e-12)


@pytest.mark.parametrize("length,width", FOOTPRINTS)
def test_the_rear_face_is_at_minus_half_length(length, width):
    """The rear-most part is the bumper (cars) or the rear frame (trucks), at -L/2 over a real height range."""
    t, _, _, _ = vehicle_faces_detailed(length, width, RED, 0.0, 0)
    v = t.reshape(-1, 3)
    rear = v[np.abs(v[:, 0] + length / 2) < 1e-9]
    lo, hi = (1.15, 3.6) if vehicle_layout(length, width).truck else (0.30, 0.56)
    assert rear[:, 2].min() <= lo + 1e-9 and rear[:, 2].max() >= hi - 1e-9


def test_dirt_band_grows_and_is_browner_and_darker():
    tops, strengths = [], []
    for dirt in (0.0, 0.2, 0.5, 1.0):
        t, _, a, m = vehicle_faces_detailed(4.6, 1.85, WHITE, dirt, 2)
        d = m == Material.DIRT
        if dirt == 0:
            assert not d.any()
            continue
        tops.append(t[d][:, :, 2].max())
        col = a[d]
        lum = col @ [0.2126, 0.7152, 0.0722]
        assert (lum < np.dot(WHITE, [0.2126, 0.7152, 0.0722])).all()           # darker than the paint
        assert (col[:, 0] > col[:, 2] + 5).all()                                # browner: red over blue
        strengths.append(np.linalg.norm(col - WHITE, axis=1).max())
        assert t[d][:, :, 2].min() >= 0.29                                      # above the dark sill
    assert np.all(np.diff(tops) > 0) and np.all(np.diff(strengths) > 0)


def test_triangle_budget():
    for length, width in CARS + VANS:
        for seed in range(4):
            assert len(vehicle_faces_detailed(length, width, RED, 1.0, seed)[0]) <= 2500
    for length, width in TRUCKS:
        for seed in range(4):
            assert len(vehicle_faces_detailed(length, width, RED, 1.0, seed)[0]) <= 4000


# ------------------------------------------------------------------------------------------- ray casting
def _first_hits(tris: np.ndarray, origin: np.ndarray, dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Moller-Trumbore: per ray the index of the first triangle hit (-1: none) and its distance."""
    e1, e2 = tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    p = np.cross(dirs[:, None, :], e2[None])                       # (R, T, 3)
    det = np.einsum("rtk,tk->rt", p, e1)
    ok = np.abs(det) > 1e-12
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = origin[None, :] - tris[:, 0]                               # (T, 3)
    u = np.einsum("tk,rtk->rt", s, p) * inv
    q = np.cross(s, e1)                                            # (T, 3)
    v = np.einsum("rk,tk->rt", dirs, q) * inv
    dist = np.einsum("tk,tk->t", e2, q)[None, :] * inv
    hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (dist > 1e-9)
    dist = np.where(hit, dist, np.inf)
    idx = dist.argmin(axis=1)
    best = dist[np.arange(len(dirs)), idx]
    return np.where(np.isfinite(best), idx, -1), best


@pytest.mark.parametrize("length,width", [(4.6, 1.85), (6.5, 2.1), (12.0, 2.5)])
@pytest.mark.parametrize("view", ["behind", "behind_left", "side", "front", "above"])
def test_seen_faces_face_the_viewer(length, width, view):
    """Back-face culling keeps only faces wound towards the camera: every face a ray from the camera hits first
    must face it (a decal wound the wrong way would vanish in the render)."""
    t, n, _, _ = vehicle_faces_detailed(length, width, RED, 0.5, 1)
    H = vehicle_height(length, width)
    eye = {"behind": (-length / 2 - 12, 0.0, 1.3), "behind_left": (-length / 2 - 8, 3.5, 1.5),
           "side": (0.0, -8.0, 1.4), "front": (length / 2 + 10, -1.0, 1.4), "above": (-length / 2 - 4, 0.5, 6.0)}[view]
    eye = np.array(eye)
    # aim points inside the box, off the round numbers the parts are placed at (no ray grazes an edge exactly)
    xs = np.linspace(-0.97, 0.97, 15) * length / 2 + 0.00123
    ys = np.linspace(-0.97, 0.97, 11) * width / 2 + 0.00071
    zs = np.linspace(0.02, H - 0.02, 17) + 0.00037
    targets = np.array([(x, y, z) for x in xs[::3] for y in ys for z in zs] + [(x, y, z) for x in xs for y in ys[::5]
                                                                                for z in zs])
    dirs = targets - eye
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    idx, _ = _first_hits(t, eye, dirs)
    seen = idx >= 0
    assert seen.sum() > 50
    facing = np.einsum("rk,rk->r", n[idx[seen]], dirs[seen])
    # a decal floats a few mm off its surface: a line of sight grazing along the surface (within 3 degrees) may
    # pass under it and meet its back, where culling shows the surface itself; nothing else may be seen from behind
    assert (facing < np.sin(np.radians(3.0))).all(), f"{(facing >= 0.05).sum()} faces seen from their back"
    assert (facing < 0).mean() > 0.99


def _luma(rgb: np.ndarray) -> np.ndarray:
    return srgb_to_linear(np.asarray(rgb) * 255.0) @ [0.2126, 0.7152, 0.0722]


def _band_ratio(t, n, a, m, length, distance, sun, sky, road):
    """Mean linear luminance of what a dashcam (1.3 m high, ``distance`` m behind the rear bumper) sees of the
    ground under the vehicle, over that of the open road (rays through the rear plane, |y| < 0.5 m)."""
    eye = np.array([-length / 2 - distance, 0.0, 1.3])
    targets = np.array([(-length / 2, y, z) for y in np.linspace(-0.5, 0.5, 9) for z in np.linspace(0.0, 0.6, 61)])
    dirs = targets - eye
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    idx, dist = _first_hits(t, eye, dirs)
    t_ground = -eye[2] / dirs[:, 2]
    ground_x = eye[0] + t_ground * dirs[:, 0]
    car = (idx >= 0) & (dist < t_ground)
    light = np.array([0.3, -0.2, -0.93])
    light /= np.linalg.norm(light)
    car_rgb = shade_realistic(a, n, m, light, sun, sky, 0.5, ground_srgb=road)
    road_rgb = shade_matte(np.array([road], float), np.array([[0.0, 0.0, 1.0]]), light, sun, sky, ground_srgb=road)
    lum = np.where(car, _luma(car_rgb[np.where(car, idx, 0)]), _luma(road_rgb)[0])
    hit_z = eye[2] + np.where(car, dist, t_ground) * dirs[:, 2]
    # lines of sight that pass under the body and end on the ground (or a few cm above it) under the footprint
    under = (hit_z < 0.05) & (ground_x > -length / 2) & (ground_x < length / 2)
    assert under.sum() >= 9
    return lum[under].mean() / _luma(road_rgb)[0]

@pytest.mark.parametrize("length,width", [(4.6, 1.85), (12.0, 2.5)])
@pytest.mark.parametrize("distance", [10.0, 20.0, 40.0])
def test_dark_band_under_the_body_seen_from_behind(length, width, distance):
    """From behind, the ground seen under a detailed vehicle is far darker than the road (its contact shadow);
    under the simple mesh, shaded the simple way, it is the road itself."""
    sun = SunLook(elevation_deg=40.0, azimuth_deg=150.0, intensity=3.0, ambient=0.5, shadow_strength=0.8)
    sky = SkyLook(zenith_srgb=(90, 140, 210), horizon_srgb=(205, 215, 225), cloud_cover=0.1, cloud_seed=0)
    road = (85, 85, 87)
    t, n, a, m = vehicle_faces_detailed(length, width, WHITE, 0.0, 0)
    assert _band_ratio(t, n, a, m, length, distance, sun, sky, road) < 0.5
    ts, ns, as_ = vehicle_faces(length, width, WHITE)
    ratio_simple = _band_ratio(ts, ns, as_, np.full(len(ts), int(Material.MATTE)), length, distance, sun, sky, road)
    assert ratio_simple > 0.9
