"""The realistic look's material model (harness.render.materials): closed forms of the sun and sky terms,
shadows, reflections that grow with gloss and with how much a face looks at the sky, matte tyres and dirt,
lamps that look lit, and the dark ground under a vehicle."""

from __future__ import annotations

import math

import numpy as np
import pytest

from harness.render.look import SkyLook, SunLook, sample_look
from harness.render.materials import Material, shade_matte, shade_realistic, sun_light_dir
from harness.render.shading import shade

GREY_SKY = SkyLook(zenith_srgb=(180, 180, 180), horizon_srgb=(200, 200, 200), cloud_cover=0.5, cloud_seed=0)
BLUE_SKY = SkyLook(zenith_srgb=(85, 135, 210), horizon_srgb=(205, 214, 226), cloud_cover=0.1, cloud_seed=0)
ALBEDOS = np.array([(170, 25, 30), (235, 235, 232), (60, 60, 62), (25, 55, 130), (128, 128, 128)], float)


def _sun(elevation=40.0, azimuth=30.0, intensity=3.0, ambient=0.5, shadow=0.75) -> SunLook:
    return SunLook(elevation_deg=elevation, azimuth_deg=azimuth, intensity=intensity, ambient=ambient,
                   shadow_strength=shadow)


def _lin(srgb01: np.ndarray) -> np.ndarray:
    return np.asarray(srgb01, float) ** 2.2


def _luma(srgb01: np.ndarray) -> np.ndarray:
    return _lin(srgb01) @ [0.2126, 0.7152, 0.0722]


def _tags(material: Material, n: int) -> np.ndarray:
    return np.full(n, int(material))


@pytest.mark.parametrize("intensity,ambient", [(3.0, 0.5), (2.4, 0.4), (1.0, 0.6)])
def test_upward_matte_face_under_the_sun_is_the_simple_model(intensity, ambient):
    """Sun overhead, grey sky: an upward matte face is lit by the whole sky (ambient) plus the full sun, which is
    exactly shading.shade's Lambert + ambient (an independent implementation)."""
    sun = _sun(elevation=90.0, intensity=intensity, ambient=ambient)
    grey = SkyLook(zenith_srgb=(190, 190, 190), horizon_srgb=(190, 190, 190), cloud_cover=0.5, cloud_seed=0)
    n = np.tile([0.0, 0.0, 1.0], (len(ALBEDOS), 1))
    light = np.array([0.0, 0.0, -1.0])
    got = shade_realistic(ALBEDOS, n, _tags(Material.MATTE, len(n)), light, sun, grey, 0.5)
    np.testing.assert_allclose(got, shade(ALBEDOS, n, light, intensity, ambient), atol=1e-12)
    np.testing.assert_allclose(shade_matte(ALBEDOS, n, light, sun, grey), got, atol=1e-12)


def test_vertical_face_facing_a_low_sun_closed_form():
    """A vertical face looking straight at a sun on the horizon, grey sky, black ground: half the sky's ambient
    (the upper hemisphere) plus the full direct term, nothing from below."""
    sun = _sun(elevation=0.0, azimuth=0.0, intensity=2.0, ambient=0.5)
    grey = SkyLook(zenith_srgb=(150, 150, 150), horizon_srgb=(150, 150, 150), cloud_cover=0.5, cloud_seed=0)
    n = np.tile([1.0, 0.0, 0.0], (len(ALBEDOS), 1))
    light = sun_light_dir(sun)
    got = shade_realistic(ALBEDOS, n, _tags(Material.MATTE, len(n)), light, sun, grey, 0.0, ground_srgb=(0, 0, 0))
    want = np.clip((ALBEDOS / 255.0) ** 2.2 * (0.5 * 0.5 + 2.0 / math.pi), 0, 1) ** (1 / 2.2)
    np.testing.assert_allclose(got, want, atol=1e-12)


def test_sun_light_dir_points_from_the_sun():
    np.testing.assert_allclose(sun_light_dir(_sun(elevation=90.0)), [0, 0, -1], atol=1e-12)
    np.testing.assert_allclose(sun_light_dir(_sun(elevation=0.0, azimuth=0.0)), [-1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(sun_light_dir(_sun(elevation=0.0, azimuth=90.0)), [0, -1, 0], atol=1e-12)
    e, a = math.radians(30), math.radians(-120)
    np.testing.assert_allclose(sun_light_dir(_sun(elevation=30.0, azimuth=-120.0)),
                               [-math.cos(e) * math.cos(a), -math.cos(e) * math.sin(a), -math.sin(e)], atol=1e-12)


@pytest.mark.parametrize("material", [Material.MATTE, Material.PAINT, Material.TRIM, Material.DIRT, Material.TYRE])
def test_shadow_removes_shadow_strength_of_the_direct_term(material):
    sun = _sun(elevation=35.0, azimuth=60.0, intensity=3.0, shadow=0.7)
    light = sun_light_dir(sun)
    to_sun = -light
    dim = ALBEDOS * 0.5                      # stay clear of clipping at 1
    n = np.tile(to_sun, (len(dim), 1))
    tags = _tags(material, len(dim))
    lit = _lin(shade_realistic(dim, n, tags, light, sun, BLUE_SKY, 0.6))
    dark = _lin(shade_realistic(dim, n, tags, light, sun, BLUE_SKY, 0.6, in_shadow=np.ones(len(dim), bool)))
    half = _lin(shade_realistic(dim, n, tags, light, sun, BLUE_SKY, 0.6, in_shadow=np.full(len(dim), 0.5)))
    direct = (dim / 255.0) ** 2.2 * 3.0 / math.pi                 # the face looks straight at the sun
    np.testing.assert_allclose(lit - dark, 0.7 * direct, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(lit - half, 0.35 * direct, rtol=1e-9, atol=1e-12)
    # a face turned away from the sun has no direct light to lose
    away = np.tile(light, (len(dim), 1))
    np.testing.assert_allclose(shade_realistic(dim, away, tags, light, sun, BLUE_SKY, 0.6),
                               shade_realistic(dim, away, tags, light, sun, BLUE_SKY, 0.6, np.ones(len(dim))))


@pytest.mark.parametrize("look_seed", range(8))
def test_glass_facing_up_is_brighter_than_glass_facing_sideways(look_seed):
    look = sample_look(look_seed)
    light = sun_light_dir(look.sun)
    glass = np.array([(26, 32, 40)] * 6, float)
    n = np.array([(0, 0, 1), (0.6, 0, 0.8), (1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0)], float)
    out = shade_realistic(glass, n, _tags(Material.GLASS, 6), light, look.sun, look.sky, look.vehicle.gloss)
    lum = _luma(out)
    assert min(lum[0], lum[1]) > lum[2:].max()          # roof and a raked rear window over the sides
    # and it is a reflection of the sky: far brighter than the same dark albedo would be as matte plastic
    matte = shade_realistic(glass, n, _tags(Material.TRIM, 6), light, look.sun, look.sky, look.vehicle.gloss)
    assert (lum > _luma(matte)).all()


def test_roof_paint_is_brighter_than_side_paint_without_sun():
    sun = _sun(intensity=0.0)
    paint = np.array([(25, 55, 130)] * 2, float)
    n = np.array([(0, 0, 1), (0, 1, 0)], float)
    out = shade_realistic(paint, n, _tags(Material.PAINT, 2), sun_light_dir(sun), sun, BLUE_SKY, 0.8)
    assert _luma(out)[0] > _luma(out)[1]


@pytest.mark.parametrize("normal", [(0, 0, 1), (0.5, 0.3, 0.81), (0, 1, 0), (-1, 0, 0), (0, 0.6, -0.8)])
def test_paint_is_monotone_in_gloss_and_matte_materials_ignore_it(normal):
    sun = _sun()
    light = sun_light_dir(sun)
    n = np.tile(np.asarray(normal, float) / np.linalg.norm(normal), (len(ALBEDOS), 1))
    glosses = np.linspace(0.0, 1.0, 11)
    paint = np.stack([_lin(shade_realistic(ALBEDOS * 0.6, n, _tags(Material.PAINT, len(n)), light, sun, BLUE_SKY, g))
                      for g in glosses])
    assert (np.diff(paint, axis=0) >= 0).all()
    assert (paint[-1] > paint[0]).all()                     # gloss adds a reflection on every face
    for material in (Material.MATTE, Material.TYRE, Material.DIRT, Material.GLASS, Material.SHADOW):
        outs = [shade_realistic(ALBEDOS, n, _tags(material, len(n)), light, sun, BLUE_SKY, g) for g in (0.0, 0.5, 1.0)]
        np.testing.assert_array_equal(outs[0], outs[1])
        np.testing.assert_array_equal(outs[0], outs[2])


def test_tyres_and_dirt_are_matte():
    sun = _sun()
    light = sun_light_dir(sun)
    n = np.array([(0, 0, 1), (0, 1, 0), (0.6, 0, 0.8), (-1, 0, 0)], float)
    alb = np.array([(22, 22, 22), (120, 100, 80), (90, 90, 90), (40, 40, 40)], float)
    matte = shade_realistic(alb, n, _tags(Material.MATTE, 4), light, sun, BLUE_SKY, 1.0)
    for material in (Material.TYRE, Material.DIRT):
        np.testing.assert_array_equal(shade_realistic(alb, n, _tags(material, 4), light, sun, BLUE_SKY, 1.0), matte)


def test_lamps_look_lit_and_keep_their_hue():
    sun = _sun()
    light = sun_light_dir(sun)
    lamps = np.array([(150, 8, 10), (225, 125, 25), (215, 215, 210)], float)
    n = np.tile([-1.0, 0.0, 0.0], (3, 1))                   # rear faces, away from a sun ahead
    lit = shade_realistic(lamps, n, _tags(Material.LIGHT, 3), light, sun, BLUE_SKY, 0.5)
    matte = shade_realistic(lamps, n, _tags(Material.MATTE, 3), light, sun, BLUE_SKY, 0.5)
    assert (_luma(lit) > 1.3 * _luma(matte)).all()
    assert lit[0, 0] > 2 * lit[0, 1] and lit[1, 0] > lit[1, 1] > lit[1, 2]   # red stays red, amber amber


def test_shadow_material_sees_only_part_of_the_sky():
    """The ground under a vehicle: no sun (whatever its strength or the shadow flag), darker than the road."""
    road = np.array([(85, 85, 87)], float)
    up = np.array([[0.0, 0.0, 1.0]])
    out = []
    for intensity in (0.5, 3.0):
        sun = _sun(intensity=intensity)
        light = sun_light_dir(sun)
        out.append(shade_realistic(np.array([(58, 58, 58)], float), up, _tags(Material.SHADOW, 1), light, sun,
                                   BLUE_SKY, 0.5))
        road_rgb = shade_matte(road, up, light, sun, BLUE_SKY)
        assert _luma(out[-1])[0] < 0.5 * _luma(road_rgb)[0]
    np.testing.assert_array_equal(out[0], out[1])


def test_output_range_shape_and_determinism():
    rng = np.random.default_rng(3)
    n = rng.normal(size=(200, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    alb = rng.uniform(0, 255, (200, 3))
    mat = rng.integers(0, len(Material), 200)
    shadow = rng.uniform(size=200) < 0.5
    look = sample_look(5)
    args = (alb, n, mat, sun_light_dir(look.sun), look.sun, look.sky, look.vehicle.gloss, shadow,
            look.surface.asphalt_srgb)
    a, b = shade_realistic(*args), shade_realistic(*args)
    assert a.shape == (200, 3) and np.isfinite(a).all() and (a >= 0).all() and (a <= 1).all()
    assert a.tobytes() == b.tobytes()
