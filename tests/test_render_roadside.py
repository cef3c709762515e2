"""Roadside geometry and sky of the realistic look (harness/render/roadside.py, sky.py): the
clear band stays clear (straight and curved, level and graded), shadows have their closed-form
lengths, the dome faces inwards with the look's colours, and everything is seeded."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from harness.render import roadside, scenery, sky
from harness.render.look import RoadsideLook, SkyLook, sample_look
from harness.world.road_plan import RoadPlan
from harness.world.road_profile import RoadProfile
from harness.world.scenario import Road

ROAD = Road(lanes=3, lane_width_m=3.75, length_m=800, shoulder_width_m=2.5)
BUSY = RoadsideLook(guard_rail=True, median="concrete", tree_form="broadleaf", tree_density=6.0, tree_setback_m=4.0,
                    bush_density=8.0, pole_spacing_m=40.0, sign_density=0.5, gantry_spacing_m=300.0,
                    building_density=1.5, hill_height_m=60.0, layout_seed=1234)
PLAN = RoadPlan(starts=(150.0, 520.0), transitions=(60.0, 40.0), lengths=(200.0, 120.0),
                curvatures=(1 / 150.0, -1 / 120.0))
PROFILE = RoadProfile(starts=(100.0, 450.0), lengths=(150.0, 200.0), grades=(0.06, -0.04))


def sun(elevation_deg: float, azimuth_deg: float) -> np.ndarray:
    """Direction sunlight travels (W) for a sun at that elevation and azimuth (from +X towards +Y)."""
    e, a = math.radians(elevation_deg), math.radians(azimuth_deg)
    return -np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])


def band(road: Road) -> tuple[float, float]:
    """The clear band in road y, from the road's own numbers (edge lines at (i - 0.5) * lane width)."""
    return (-0.5 * road.lane_width_m - road.shoulder_width_m - 0.5,
            (road.lanes - 0.5) * road.lane_width_m + road.shoulder_width_m + 0.5)


def road_coords(points: np.ndarray, plan: RoadPlan | None, chunk: int = 4000) -> tuple[np.ndarray, np.ndarray]:
    """Road (x, y) of W points (N, 3): Y = -y on the straight road, the plan's inverse on a curved one."""
    if plan is None:
        return points[:, 0], -points[:, 1]
    flat, back = np.unique(np.stack([points[:, 0], -points[:, 1]], -1), axis=0, return_inverse=True)
    xs, ys = [], []
    for i in range(0, len(flat), chunk):
        x, y = plan.from_plane(flat[i:i + chunk])
        xs.append(x)
        ys.append(y)
    return np.concatenate(xs)[back.ravel()], np.concatenate(ys)[back.ravel()]


@pytest.fixture(scope="module")
def curved():
    return scenery.roadside_geometry(ROAD, PROFILE, PLAN, BUSY, sun(35, 70))


@pytest.fixture(scope="module")
def straight():
    return scenery.roadside_geometry(ROAD, None, None, BUSY, sun(35, 70))


def _check_clear(geom: roadside.RoadsideGeometry, plan, profile) -> None:
    """No vertex in the band, and no triangle reaching over it (a beam has vertices only at its
    ends), but gantries >= 5.5 m above the road."""
    occ = geom.occluders
    pts = occ.triangles.reshape(-1, 3)
    x, y = road_coords(pts, plan)
    z = profile.z(x) if profile is not None else np.zeros_like(x)
    x, y, above = x.reshape(-1, 3), y.reshape(-1, 3), (pts[:, 2] - z).reshape(-1, 3)
    lo, hi = band(ROAD)
    over = (y.min(axis=1) < hi) & (y.max(axis=1) > lo)                   # the triangle's span meets the band
    gantry = occ.kind == roadside.KINDS.index("gantry")
    assert over.any(), "no gantry spans the road: the test would check nothing above the lanes"
    assert np.all(gantry[over]), sorted({roadside.KINDS[k] for k in occ.kind[over]})
    assert above[over].min() >= 5.5 - 1e-6
    assert -300 - 10 < x.min() and x.max() < ROAD.length_m + 300 + 10      # along the road and ~300 m beyond


def test_nothing_stands_on_the_carriageway_or_shoulders(straight):
    assert {roadside.KINDS[k] for k in np.unique(straight.occluders.kind)} == {
        "rail", "median", "tree", "bush", "pole", "sign", "gantry"}
    _check_clear(straight, None, None)


def test_the_band_stays_clear_on_curves_and_grades(curved):
    _check_clear(curved, PLAN, PROFILE)


def test_rail_and_median_follow_the_plan_and_profile(curved):
    """Swept along the road: the same road-frame offset and height above the road everywhere."""
    lo, hi = band(ROAD)
    for kind, (y0, y1), (h0, h1) in (("rail", (hi + 0.2, hi + 0.55), (-0.35, 0.8)),
                                     ("median", (lo - 0.85, lo - 0.15), (-0.1, 0.85))):
        pts = curved.occluders.of(kind).triangles.reshape(-1, 3)
        x, y = road_coords(pts, PLAN)
        assert y.min() > y0 and y.max() < y1          # the rail right of the road, the median left of it
        h = pts[:, 2] - PROFILE.z(x)                   # rail posts reach 0.3 m into the ground
        assert h.min() > h0 and h.max() < h1
        assert x.min() < PLAN.starts[0] and x.max() > PLAN.starts[1] + 2 * PLAN.transitions[1] + PLAN.lengths[1]


def test_faces_point_outwards_from_convex_primitives():
    rng = np.random.default_rng(0)
    c = rng.uniform(-5, 5, (4, 3))
    cases = [roadside.boxes(c, rng.uniform(0.2, 3, (4, 3)), bottom=True),
             roadside.frustums(c, c + rng.uniform(-1, 1, (4, 3)) + [0, 0, 3], rng.uniform(0.2, 1, 4),
                               rng.uniform(0.1, 0.5, 4), 7, top=True, bottom=True),
             roadside.frustums(c, c + [0, 0, 4], rng.uniform(0.5, 2, 4), np.zeros(4), 8, bottom=True),
             roadside.blobs(rng, c, rng.uniform(0.5, 3, (4, 3)), 1, 0.15)]
    for verts, faces in cases:
        t = verts[:, faces]                                          # (n, F, 3, 3)
        normal = np.cross(t[..., 1, :] - t[..., 0, :], t[..., 2, :] - t[..., 0, :])
        out = t.mean(axis=2) - verts.mean(axis=1, keepdims=True)
        assert np.all(np.einsum("nfk,nfk->nf", normal, out) > 0)


def test_the_median_is_wound_outwards(straight):
    """The jersey barrier's faces point away from its own axis (seen from the road: front faces)."""
    m = straight.occluders.of("median")
    lo, _ = band(ROAD)
    axis = np.array([-(lo - 0.2 - 0.305), 0.3])                         # its centre line (Y, Z)
    centroid = m.triangles.mean(axis=1)[:, 1:]
    assert np.all(np.sum(m.normals[:, 1:] * (centroid - axis), axis=1) > 0)
    assert np.allclose(np.linalg.norm(m.normals, axis=1), 1)


@pytest.mark.parametrize("elevation", [15.0, 35.0, 60.0])
def test_a_pole_casts_a_shadow_h_over_tan_e(elevation):
    h, r = 7.0, 1e-3
    verts, _ = roadside.frustums(np.array([[10.0, 20.0, -0.5]]), np.array([[10.0, 20.0, h]]),  # 0.5 m in the ground
                                 np.array([r]), np.array([r]), 8)
    s = sun(elevation, 37.0)
    tri = roadside.ground_shadows([verts[0]], s)
    along = s[:2] / np.linalg.norm(s[:2])
    d = tri[..., :2].reshape(-1, 2) @ along
    assert d.max() - d.min() == pytest.approx(h / math.tan(math.radians(elevation)) + 2 * r, abs=2e-3)
    assert d.min() == pytest.approx(np.array([10.0, 20.0]) @ along - r, abs=2e-3)  # from the foot, away from the sun
    assert np.all((tri[..., 2] >= 0.02 - 1e-9) & (tri[..., 2] <= 0.03 + 1e-9))
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    assert np.all(normal[:, 2] > 0)                                       # facing up


@pytest.mark.parametrize("uphill", [True, False])
def test_a_pole_shadow_on_a_grade(uphill):
    """On a uniform grade g, light travelling up the slope: length h / (tan e + g); down it: h / (tan e - g)."""
    g, h, e = 0.08, 6.0, 30.0
    ground = roadside.Ground(RoadProfile(starts=(0.0,), lengths=(0.0,), grades=(g,)))
    x0 = 100.0
    verts, _ = roadside.frustums(np.array([[x0, 0.0, g * x0 - 0.3]]), np.array([[x0, 0.0, g * x0 + h]]),
                                 np.array([1e-3]), np.array([1e-3]), 8)
    s = sun(e, 180.0 if uphill else 0.0)                                 # sun behind: light travels +X
    tri = roadside.ground_shadows([verts[0]], s, ground)
    length = np.ptp(tri[..., 0]) - 2e-3
    expect = h / (math.tan(math.radians(e)) + (g if uphill else -g))
    assert length == pytest.approx(expect, abs=5e-3)
    lift = tri[..., 2] - g * tri[..., 0]
    assert lift.min() >= 0.02 - 1e-6 and lift.max() <= 0.03 + 1e-6


def test_a_pole_shadow_on_a_vertical_curve():
    """On a sag z = q u^2 (u = x - x_s, q = dg / 2L) the tip of the shadow of a pole at u0 under
    light along +X, elevation e, is at u0 + t cos e with q (u0 + t cos e)^2 = q u0^2 + h - t sin e."""
    x_s, length, g, h, e = 100.0, 400.0, 0.12, 8.0, 20.0
    ground = roadside.Ground(RoadProfile(starts=(x_s,), lengths=(length,), grades=(g,)))
    q, u0 = g / (2 * length), 150.0
    z0 = q * u0 ** 2
    verts, _ = roadside.frustums(np.array([[x_s + u0, 0.0, z0 - 0.3]]), np.array([[x_s + u0, 0.0, z0 + h]]),
                                 np.array([1e-3]), np.array([1e-3]), 8)
    tri = roadside.ground_shadows([verts[0]], sun(e, 180.0), ground, max_edge_m=1.0)
    ce, se = math.cos(math.radians(e)), math.sin(math.radians(e))
    # q ce^2 t^2 + (2 q u0 ce + se) t - h = 0
    a, b = q * ce * ce, 2 * q * u0 * ce + se
    t = (-b + math.sqrt(b * b + 4 * a * h)) / (2 * a)
    assert tri[..., 0].max() - 1e-3 == pytest.approx(x_s + u0 + t * ce, abs=5e-3)
    mids = (tri + np.roll(tri, -1, axis=1)) / 2                            # the surface between the vertices too
    for p in (tri, mids):
        lift = p[..., 2] - q * (p[..., 0] - x_s) ** 2
        assert lift.min() >= 0.02 - 1e-4 and lift.max() <= 0.03 + 1e-4      # cut small enough to follow the sag


def test_shadows_lie_on_the_graded_curved_ground_and_cross_the_road(curved):
    sh = curved.shadows
    pts = sh.reshape(-1, 3)
    x, y = road_coords(pts, PLAN)
    lift = pts[:, 2] - PROFILE.z(x)
    assert lift.min() >= 0.02 - 2e-3 and lift.max() <= 0.03 + 2e-3
    normal = np.cross(sh[:, 1] - sh[:, 0], sh[:, 2] - sh[:, 0])
    assert np.all(normal[:, 2] > 0)
    lo, hi = band(ROAD)
    on_road = (y > lo + 2) & (y < hi - 2)
    assert on_road.mean() > 0.01                                          # sun from the left: shade on the lanes


def test_gantry_shadow_falls_across_the_lanes():
    look = dataclasses.replace(BUSY, tree_density=0, bush_density=0, pole_spacing_m=0, sign_density=0,
                               guard_rail=False, median="none", gantry_spacing_m=500.0)
    g = scenery.roadside_geometry(ROAD, None, None, look, sun(40, 90))
    gx = g.occluders.of("gantry").triangles[..., 0].mean()
    lo, hi = band(ROAD)
    c = g.shadows.mean(axis=1)
    across = c[np.abs(c[:, 0] - gx) < 2]
    assert (-across[:, 1]).min() < lo + 3 and (-across[:, 1]).max() > hi - 3   # the beam's shadow spans the lanes
    assert set(np.unique(g.occluders.kind)) == {roadside.KINDS.index("gantry")}


def test_no_shadows_with_the_sun_below_the_horizon(straight):
    g = scenery.roadside_geometry(ROAD, None, None, BUSY, sun(-5, 70))
    assert len(g.shadows) == 0 and len(g.occluders) == len(straight.occluders)


def test_far_things_stay_far_and_low(straight):
    far = straight.far
    hills, houses = far.of("hill").triangles.reshape(-1, 3), far.of("building").triangles.reshape(-1, 3)
    assert len(hills) and len(houses)
    lo, hi = band(ROAD)
    lateral = np.maximum(lo - (-houses[:, 1]), (-houses[:, 1]) - hi)
    assert lateral.min() > 140 and lateral.max() < 830
    for cam_x in (0.0, ROAD.length_m):
        d = np.hypot(hills[:, 0] - cam_x, hills[:, 1])
        elevation = np.degrees(np.arctan2(hills[:, 2] - 1.3, d))
        assert d.min() > 900 and d.max() < roadside.HILL_MAX_DISTANCE_M + 1
        assert elevation.max() < 3.0 and elevation.max() > 0.3               # a ridge just above the horizon
    assert np.all(far.of("hill").normals[:, 2] > 0)                          # the slopes face the road


@pytest.mark.parametrize("form,median", [("broadleaf", "rail"), ("conifer", "concrete"),
                                         ("poplar", "concrete_low"), ("shrubby", "none")])
def test_triangle_budget_at_the_densest_look(form, median):
    look = dataclasses.replace(BUSY, tree_form=form, median=median, tree_density=8.0, bush_density=10.0,
                               building_density=2.0, hill_height_m=80.0, gantry_spacing_m=500.0)
    road = Road(length_m=2000)
    g = scenery.roadside_geometry(road, None, None, look, sun(30, 40))
    km = (road.length_m + 2 * roadside.MARGIN_M) / 1000
    assert len(g.occluders) / km <= 60_000
    assert len(g.far) <= 15_000


def test_same_seed_same_geometry_other_seed_other_layout(straight):
    again = scenery.roadside_geometry(ROAD, None, None, BUSY, sun(35, 70))
    for a, b in ((straight.occluders, again.occluders), (straight.far, again.far)):
        for f in ("triangles", "albedo", "normals", "kind"):
            assert np.array_equal(getattr(a, f), getattr(b, f))
    assert np.array_equal(straight.shadows, again.shadows)
    other = scenery.roadside_geometry(ROAD, None, None, dataclasses.replace(BUSY, layout_seed=99), sun(35, 70))
    for kind in ("tree", "bush", "sign"):
        a, b = straight.occluders.of(kind).triangles, other.occluders.of(kind).triangles
        assert a.shape != b.shape or not np.allclose(a, b)
    trees = other.occluders.of("tree")
    assert not np.array_equal(straight.occluders.of("tree").albedo[:100], trees.albedo[:100])


def test_turning_one_kind_off_leaves_the_others():
    a = scenery.roadside_geometry(ROAD, None, None, BUSY, sun(35, 70)).occluders
    b = scenery.roadside_geometry(ROAD, None, None, dataclasses.replace(BUSY, bush_density=0.0),
                                   sun(35, 70)).occluders
    assert len(b.of("bush")) == 0
    assert np.array_equal(a.of("tree").triangles, b.of("tree").triangles)


# --------------------------------------------------------------------------- sky
CLEAR = SkyLook(zenith_srgb=(70, 120, 210), horizon_srgb=(205, 215, 228), cloud_cover=0.0, cloud_seed=42)


def _dome(look: SkyLook, s: np.ndarray, radius: float = 1000.0):
    tri, col = sky.sky_dome(look, s, radius)
    return tri.reshape(-1, 3), col.reshape(-1, 3), tri, col


def test_the_dome_faces_its_centre_and_reaches_below_the_horizon():
    _, _, tri, col = _dome(CLEAR, sun(30, 0), 1000.0)
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    assert np.all(np.einsum("fk,fk->f", normal, tri.mean(axis=1)) < 0)
    r = np.linalg.norm(tri.reshape(-1, 3), axis=1)
    assert np.allclose(r, 1000.0)
    elev = np.degrees(np.arcsin(tri[..., 2] / 1000.0))
    assert elev.min() <= -3.0 and elev.max() == pytest.approx(90.0)
    assert col.shape == tri.shape and col.min() >= 0 and col.max() <= 1
    # covers every direction: the azimuths of the horizon ring close the circle
    ring = tri.reshape(-1, 3)[np.abs(tri.reshape(-1, 3)[:, 2]) < 1e-9]
    az = np.sort(np.unique(np.round(np.degrees(np.arctan2(ring[:, 1], ring[:, 0])) % 360, 6)))
    assert np.diff(np.r_[az, az[0] + 360]).max() < 4.0


def test_clear_sky_has_the_looks_colours_at_horizon_and_zenith():
    s = sun(12, 0)                                                        # the zenith 78 deg from the sun
    pts, col, _, _ = _dome(CLEAR, s)
    d = pts / np.linalg.norm(pts, axis=1, keepdims=True)
    away = np.degrees(np.arccos(np.clip(d @ -s, -1, 1))) > 75
    horizon = (np.abs(d[:, 2]) < 1e-9) & away
    below = (d[:, 2] < -1e-9) & away
    zenith = (d[:, 2] > 1 - 1e-12) & away
    assert horizon.sum() > 20 and below.sum() > 20 and zenith.sum() > 20
    assert np.allclose(col[horizon], np.array(CLEAR.horizon_srgb) / 255, atol=1e-9)
    assert np.allclose(col[below], np.array(CLEAR.horizon_srgb) / 255, atol=1e-9)
    assert np.allclose(col[zenith], np.array(CLEAR.zenith_srgb) / 255, atol=1e-9)
    _, col_other_seed, _, _ = _dome(dataclasses.replace(CLEAR, cloud_seed=7), s)
    assert np.array_equal(col, col_other_seed)                          # no cloud anywhere at cover 0
    # in between: bluer as it rises (monotone from horizon to zenith at one azimuth, away from the sun)
    opposite = away & (np.abs(np.arctan2(d[:, 1], d[:, 0])) > np.radians(179)) & (d[:, 2] >= 0)
    order = np.argsort(d[opposite, 2])
    red = col[opposite][order, 0]
    assert np.all(np.diff(red) <= 1e-12) and red[0] > red[-1]


def test_the_sky_is_brighter_around_the_sun():
    s = sun(25, 40)
    dirs = np.array([-s, -s * [-1, -1, 1]])                               # towards the sun, and opposite
    c = sky.sky_colours(CLEAR, s, dirs / np.linalg.norm(dirs, axis=1, keepdims=True))
    assert c[0].sum() > c[1].sum() + 0.2


def test_clouds_follow_the_cover_and_the_seed():
    s = sun(40, 0)
    _, clear, _, _ = _dome(CLEAR, s)
    _, half, _, _ = _dome(dataclasses.replace(CLEAR, cloud_cover=0.5), s)
    _, half2, _, _ = _dome(dataclasses.replace(CLEAR, cloud_cover=0.5), s)
    _, other, _, _ = _dome(dataclasses.replace(CLEAR, cloud_cover=0.5, cloud_seed=43), s)
    pts, over, _, _ = _dome(dataclasses.replace(CLEAR, cloud_cover=1.0), s)
    up = pts[:, 2] > 0.3 * 1000

    def chroma(c: np.ndarray) -> np.ndarray:
        return np.abs(c - c.mean(axis=1, keepdims=True)).sum(axis=1)

    greyer = chroma(half) < chroma(clear) - 0.05
    assert 0.1 < greyer[up].mean() < 0.9                                   # broken cloud: some grey, some blue
    assert np.array_equal(half, half2) and not np.allclose(half, other)
    assert np.ptp(over[up], axis=1).max() < 0.06                           # overcast: grey everywhere up there


def test_cloud_noise_tiles():
    rng = np.random.default_rng(1)
    u, v = rng.uniform(-3, 3, 500), rng.uniform(-3, 3, 500)
    n = sky.tileable_noise(7, u, v)
    assert np.allclose(n, sky.tileable_noise(7, u + 1, v)) and np.allclose(n, sky.tileable_noise(7, u, v - 2))
    assert 0 <= n.min() and n.max() <= 1 and n.std() > 0.05
    assert not np.allclose(n, sky.tileable_noise(8, u, v))


def test_a_sampled_look_builds():
    look = sample_look(11, "heldout")
    g = scenery.roadside_geometry(Road(length_m=400), None, None, look.roadside, sun(look.sun.elevation_deg,
                                                                                  look.sun.azimuth_deg))
    tri, col = sky.sky_dome(look.sky, sun(look.sun.elevation_deg, look.sun.azimuth_deg))
    assert np.isfinite(g.occluders.triangles).all() and np.isfinite(tri).all() and np.isfinite(col).all()
    assert g.occluders.albedo.dtype == np.uint8 and len(g.occluders.normals) == len(g.occluders)
