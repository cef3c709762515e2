"""A street's roadside in the realistic look (harness/render/street.py, roadside.py, road.py, look.py):
seeded, nothing on the carriageway or the parking strips, the motorway untouched, the held-out family's
variants disjoint, and the frontage, kerbs and pavements on screen."""

from __future__ import annotations

import numpy as np
import pytest

from harness.render import road as road_mod
from harness.render import roadside, scenery, street
from harness.render.look import FACADE_PALETTES, ROOF_FORMS, sample_look, sample_street, sun_direction_w
from harness.render.renderer import Renderer
from harness.world.scenario import Road, Street, parse_scenario
from harness.world.state import VehicleState, WorldState

STREET = Road(lanes=2, lane_width_m=3.25, shoulder_width_m=2.3, length_m=300.0, street=Street(parking="none"))
MOTORWAY = Road(lanes=2, lane_width_m=3.25, shoulder_width_m=2.3, length_m=300.0)
STREET_KINDS = ("kerb", "house", "facade", "boundary", "street_tree", "furniture")


def _geometry(road: Road, seed: int = 3, family: str = "train", **street_changes):
    look = sample_look(seed, family)
    st = look.street if not street_changes else type(look.street)(**{**look.street.__dict__, **street_changes})
    return scenery.roadside_geometry(road, None, None, look.roadside, sun_direction_w(look.sun), st)


@pytest.fixture(scope="module")
def geo():
    return _geometry(STREET, tree_density=8.0, wall_share=0.3, hedge_share=0.3, fence_share=0.3,
                     lamp_spacing_m=25.0, sign_density=2.0, cabinet_density=2.0)


def test_same_look_same_geometry_and_another_seed_differs(geo):
    again = _geometry(STREET, tree_density=8.0, wall_share=0.3, hedge_share=0.3, fence_share=0.3,
                      lamp_spacing_m=25.0, sign_density=2.0, cabinet_density=2.0)
    for a, b in ((geo.occluders, again.occluders), (geo.far, again.far)):
        assert np.array_equal(a.triangles, b.triangles) and np.array_equal(a.albedo, b.albedo)
    assert np.array_equal(geo.shadows, again.shadows)
    other = _geometry(STREET, seed=4)
    assert other.occluders.triangles.shape != geo.occluders.triangles.shape or \
        not np.array_equal(other.occluders.triangles, geo.occluders.triangles)


def test_every_street_kind_is_built_and_casts_shadows(geo):
    kinds = {roadside.KINDS[k] for k in np.unique(geo.occluders.kind)}
    assert set(STREET_KINDS) <= kinds
    assert not kinds & {"rail", "median", "pole", "sign", "gantry"}
    assert len(geo.shadows) > 0


def test_nothing_stands_on_the_carriageway_or_the_parking_strips(geo):
    lo, hi = roadside.clear_band(STREET)
    assert (lo, hi) == pytest.approx((-1.625 - 2.3, 1.625 + 3.25 + 2.3))
    pts = geo.occluders.triangles.reshape(-1, 3)
    y, z = -pts[:, 1], pts[:, 2]
    inside = (y > lo + 1e-6) & (y < hi - 1e-6)
    assert not np.any(inside & (z < street.OVERHEAD_M)), "something below the overhead clearance on the band"
    carriageway = (y > -1.625) & (y < 4.875)
    assert not np.any(carriageway), "something over the carriageway"
    kind = np.repeat(geo.occluders.kind, 3)
    frontage = np.isin(kind, [roadside.KINDS.index(k) for k in ("kerb", "house", "facade", "boundary")])
    assert not np.any(inside & frontage), "the frontage or a kerb on the band"
    verge = np.isin(kind, [roadside.KINDS.index(k) for k in ("tree", "bush")])
    walk = street.frontage_d(STREET.street) + scenery.STREET_TREES_BEYOND_M
    assert np.all((y[verge] < lo - walk + 1e-6) | (y[verge] > hi + walk - 1e-6))


def test_road_surfaces_of_a_street_and_of_a_motorway():
    rs, rm = road_mod.road_rectangles(STREET, 100.0), road_mod.road_rectangles(MOTORWAY, 100.0)
    assert len(rm["pavement"]) == 0 and len(rm["shoulder"]) == 2
    assert len(rs["shoulder"]) == 0 and len(rs["pavement"]) == 2
    walk = road_mod.KERB_WIDTH_M + STREET.street.pavement_m
    ys = sorted(tuple(r[2:]) for r in rs["pavement"])
    assert ys[0] == pytest.approx((-1.625 - 2.3 - walk, -1.625 - 2.3))
    assert ys[1] == pytest.approx((4.875 + 2.3, 4.875 + 2.3 + walk))
    strips = [r for r in rs["asphalt"] if r[2] < -1.625 - 0.05 or r[3] > 4.875 + 0.05]
    assert len(strips) == 2                                  # the parking strips are asphalt


def test_street_off_is_the_motorway_whatever_the_street_look():
    look = sample_look(3)
    base = scenery.roadside_geometry(MOTORWAY, None, None, look.roadside, sun_direction_w(look.sun))
    other = scenery.roadside_geometry(MOTORWAY, None, None, look.roadside, sun_direction_w(look.sun),
                                       sample_street(11, "heldout"))
    assert np.array_equal(base.occluders.triangles, other.occluders.triangles)
    assert np.array_equal(base.shadows, other.shadows)
    assert not {roadside.KINDS[k] for k in np.unique(base.occluders.kind)} & set(STREET_KINDS)
    assert roadside.clear_band(MOTORWAY) == pytest.approx((-1.625 - 2.8, 4.875 + 2.8))


def test_the_street_look_leaves_every_other_look_field_as_it_was():
    # golden values from before streets existed (the street look has its own generator)
    look = sample_look(0)
    assert (look.roadside.layout_seed, look.surface.texture_seed, look.sky.cloud_seed) == \
        (GOLDEN[0], GOLDEN[1], GOLDEN[2])


def test_held_out_streets_draw_disjoint_variants_and_seeds():
    train = [sample_street(s, "train") for s in range(40)]
    held = [sample_street(s, "heldout") for s in range(40)]
    assert {t.facade_palette for t in train} <= set(FACADE_PALETTES["train"])
    assert {t.facade_palette for t in held} <= set(FACADE_PALETTES["heldout"])
    assert {t.roof_form for t in held} <= set(ROOF_FORMS["heldout"])
    assert not set(FACADE_PALETTES["train"]) & set(FACADE_PALETTES["heldout"])
    assert not set(ROOF_FORMS["train"]) & set(ROOF_FORMS["heldout"])
    assert all(t.layout_seed % 2 == 0 for t in train) and all(t.layout_seed % 2 == 1 for t in held)
    for t in train + held:
        assert 2 <= t.storeys[0] <= t.storeys[1] <= 4 and 0 <= t.setback_m[0] <= t.setback_m[1] <= 6
        assert 6 <= t.house_width_m[0] <= t.house_width_m[1] <= 15
    a, b = _geometry(STREET, family="train"), _geometry(STREET, family="heldout")
    assert not np.array_equal(a.occluders.albedo[:100], b.occluders.albedo[:100])


def _render(road: dict) -> np.ndarray:
    sc = parse_scenario({
        "name": "street", "seed": 2, "road": {"length_m": 300.0, **road},
        "camera": {"width": 240, "height": 96, "hfov_deg": 80, "height_m": 1.65, "pitch_deg": 0.0},
        "render": {"look": "realistic"}})
    ego = VehicleState(0, 60.0, 3.25, 0.0, 10.0, 10.0, 0.0, 1, 4.5, 1.8)
    with Renderer(sc) as r:
        return r.render(WorldState(3, 0.2, ego, ())).image.astype(float)


def test_a_street_render_shows_the_frontage_kerbs_and_pavements():
    common = {"lanes": 2, "lane_width_m": 3.25, "shoulder_width_m": 2.3}
    st = _render({**common, "street": {"parking": "none"}})
    mw = _render(common)
    sides = np.r_[0:36, 204:240]
    above, below = slice(0, 44), slice(52, 96)
    diff = np.abs(st - mw).sum(axis=-1)
    assert np.mean(diff[above][:, sides] > 30) > 0.5, "no frontage where the motorway shows sky and verge"
    assert np.mean(diff[below][:, sides] > 30) > 0.2, "no kerb or pavement where the motorway shows shoulder"


GOLDEN = (803064526, 83541186, 802088680)   # sample_look(0) before harness.render.street
