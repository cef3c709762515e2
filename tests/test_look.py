"""The realistic look's parameters (harness.render.look) and the vehicle shadows (harness.render.shadows)."""

from __future__ import annotations

import math
from dataclasses import asdict

import numpy as np
import pytest

from harness.render import look, shadows


def test_sample_look_is_deterministic_and_seeds_differ():
    assert look.sample_look(3) == look.sample_look(3)
    assert look.sample_look(3) != look.sample_look(4)


def test_families_draw_disjoint_seeds_and_variants():
    train = [look.sample_look(s, "train") for s in range(40)]
    held = [look.sample_look(s, "heldout") for s in range(40)]
    seeds = lambda ps: {p.surface.texture_seed for p in ps} | {p.roadside.layout_seed for p in ps} | {p.sky.cloud_seed for p in ps}  # noqa: E731
    assert not seeds(train) & seeds(held)
    assert {p.roadside.tree_form for p in train} <= set(look.TREE_FORMS["train"])
    assert {p.roadside.tree_form for p in held} <= set(look.TREE_FORMS["heldout"])
    assert not set(look.TREE_FORMS["train"]) & set(look.TREE_FORMS["heldout"])
    assert {p.roadside.median for p in held} <= set(look.MEDIAN_KINDS["heldout"])


def test_sampled_values_stay_in_a_road_scene():
    for s in range(50):
        p = look.sample_look(s)
        assert 12 <= p.sun.elevation_deg <= 65
        assert all(0 <= c <= 255 for c in p.surface.asphalt_srgb)
        assert 0 <= p.sky.cloud_cover <= 1 and 0 <= p.sensor.vignetting < 1
        assert 1 <= p.sensor.jpeg_quality <= 100
        assert asdict(p)      # plain data all through


def test_sun_direction_points_down_from_the_given_elevation_and_azimuth():
    sun = look.SunLook(elevation_deg=30.0, azimuth_deg=90.0, intensity=3.0, ambient=0.5, shadow_strength=0.8)
    d = look.sun_direction_w(sun)
    np.testing.assert_allclose(np.linalg.norm(d), 1.0)
    np.testing.assert_allclose(d, [0.0, -math.cos(math.radians(30)), -0.5], atol=1e-12)   # sun on the left (+Y)


def test_cast_shadow_of_a_box_has_the_closed_form_length():
    # sun straight along -X at elevation e: the shadow reaches h / tan(e) beyond the box's rear.
    e = math.radians(25.0)
    light = np.array([-math.cos(e), 0.0, -math.sin(e)])
    tri = shadows.cast_shadow(4.0, 2.0, 1.5, light)
    xs, ys = tri[..., 0], tri[..., 1]
    assert xs.min() == pytest.approx(-2.0 - 1.5 / math.tan(e))
    assert xs.max() == pytest.approx(2.0) and ys.min() == pytest.approx(-1.0) and ys.max() == pytest.approx(1.0)
    u, v = tri[:, 1, :2] - tri[:, 0, :2], tri[:, 2, :2] - tri[:, 0, :2]
    area = 0.5 * np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]).sum()
    assert area == pytest.approx(2.0 * (4.0 + 1.5 / math.tan(e)))
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    assert (normals[:, 2] > 0).all()                 # faces up: drawn, not culled, seen from above
    assert np.allclose(tri[..., 2], shadows.SHADOW_LIFT_M)


def test_no_shadow_without_sun_from_above():
    assert shadows.cast_shadow(4.0, 2.0, 1.5, np.array([1.0, 0.0, 0.2])).shape == (0, 3, 3)


def test_shadow_alpha_darkens_to_the_shaded_value():
    e, amb, inten, strength = math.radians(40), 0.5, 3.0, 0.8
    a = shadows.shadow_alpha(amb, inten, e, strength)
    direct = inten / math.pi * math.sin(e)
    lit_srgb, shade_srgb = (amb + direct) ** (1 / 2.2), (amb + 0.2 * direct) ** (1 / 2.2)
    assert (1 - a) * lit_srgb == pytest.approx(shade_srgb)
    assert shadows.shadow_alpha(amb, inten, e, 0.0) == pytest.approx(0.0)


def test_fleet_colours_follow_the_fleet_shares():
    from harness.render.realistic import FLEET_PAINTS, FLEET_SHARES, fleet_color

    colours = np.array([fleet_color(3, i) for i in range(3000)], dtype=float)
    nearest = np.argmin(((colours[:, None, :] - FLEET_PAINTS[None]) ** 2).sum(-1), axis=1)
    share = np.bincount(nearest, minlength=len(FLEET_PAINTS)) / len(colours)
    expected = FLEET_SHARES / FLEET_SHARES.sum()
    assert np.abs(share - expected).max() < 0.025          # 3000 draws: binomial sd <= 0.008
    assert fleet_color(3, 17) == fleet_color(3, 17)
