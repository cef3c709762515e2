"""Road textures (harness.render.textures): tileable against cv2 on a tiled lattice, seeded, toned to
the look, with the wheel tracks, seams, grain and paint wear the look asks for; texture coordinates
of the road (harness.render.road.road_surface_uv) on the same triangles as road_trimeshes, from the
road frame (plan.from_plane); textured draws in harness.render.passes equal to pyrender's own FLAT
render, with the texel orientation and vertex-colour product the module documents."""

from __future__ import annotations

import contextlib
import dataclasses
import math
import time
import types

import cv2
import numpy as np
import pyrender
import pytest
import trimesh
from OpenGL import GL

from harness.render import renderer as rmod  # noqa: F401  (first: sets PYOPENGL_PLATFORM)
from harness.render import passes, road, shading, textures
from harness.render.look import SurfaceLook, sample_look
from harness.world.road import road_plan, road_profile
from harness.world.scenario import parse_scenario

LANE_W = 3.7
BASE = SurfaceLook(asphalt_srgb=(80, 80, 82), aggregate_contrast=0.3, wheel_track_wear=0.0, patch_density=0.0,
                   seam_spacing_m=0.0, marking_wear=0.3, grass_srgb=(90, 110, 50), shoulder_srgb=(95, 92, 88),
                   texture_seed=1234)


def _look(**kw) -> SurfaceLook:
    return dataclasses.replace(BASE, **kw)


def _lum(tex: np.ndarray) -> np.ndarray:
    return tex.astype(float).mean(axis=2)


def _row(v: float, h: int) -> int:
    """The texture row sampled at v (documented: row 0 at v = 1)."""
    return h - 1 - int(v * h)


# ------------------------------------------------------------------------------ textures
@pytest.mark.parametrize("fy, fx", [(2, 4), (8, 8), (64, 32), (128, 256)])
def test_periodic_scaling_is_cv2_resize_of_a_tiled_lattice(fy, fx):
    lattice = np.random.default_rng(0).standard_normal((256 // fy, 1024 // fx)).astype(np.float32)
    out = textures._scale_periodic(lattice, fy, fx)
    h, w = lattice.shape
    tiled = cv2.resize(np.tile(lattice, (3, 3)), (3 * w * fx, 3 * h * fy), interpolation=cv2.INTER_CUBIC)
    assert out.shape == (256, 1024)
    assert np.abs(out - tiled[h * fy:2 * h * fy, w * fx:2 * w * fx]).max() < 1e-4   # the centre tile: periodic


def test_textures_seeded_sized_fast_and_toned():
    look = sample_look(5).surface
    t0 = time.perf_counter()
    tex = textures.road_textures(look, LANE_W)
    elapsed = time.perf_counter() - t0
    assert elapsed < 1.5                                        # ~0.2 s on one free core; the machine is shared
    again = textures.road_textures(look, LANE_W)
    other = textures.road_textures(dataclasses.replace(look, texture_seed=look.texture_seed + 2), LANE_W)
    for kind, t in tex.items():
        assert t.dtype == np.uint8 and t.ndim == 3 and t.shape[2] == 3 and t.shape[0] * t.shape[1] <= 1024 * 256
        assert np.array_equal(t, again[kind]) and not np.array_equal(t, other[kind])
    for kind, colour in (("asphalt", look.asphalt_srgb), ("shoulder", look.shoulder_srgb), ("grass", look.grass_srgb)):
        assert np.abs(textures.mean_srgb(tex[kind]) - colour).max() < 0.6, kind


def test_grain_follows_aggregate_contrast_and_averages_away():
    def high_pass_std(contrast):
        t = _lum(textures.asphalt_texture(_look(aggregate_contrast=contrast), LANE_W))
        return (t - cv2.GaussianBlur(t, (0, 0), 2.0, borderType=cv2.BORDER_REFLECT)).std(), t
    low, _ = high_pass_std(0.15)
    high, t = high_pass_std(0.45)
    assert 2.2 < high / low < 3.8                              # grain amplitude ~ contrast (3x)
    assert high > 6.0                                          # visible up close (8-bit levels)
    far = cv2.resize(t, (t.shape[1] // 32, t.shape[0] // 32), interpolation=cv2.INTER_AREA)   # a coarse mip level
    assert far.std() < 0.25 * t.std() and abs(far.mean() - 80.0) < 1.0


@pytest.mark.parametrize("wear", [-0.6, 0.6])
def test_wheel_tracks_darker_or_lighter(wear):
    t = _lum(textures.asphalt_texture(_look(wheel_track_wear=wear), LANE_W))
    h = t.shape[0]
    track = np.mean([t[_row(0.5 + s * 0.85 / LANE_W, h)].mean() for s in (-1, 1)])
    beside = np.mean([t[_row(0.5 + s * 1.55 / LANE_W, h)].mean() for s in (-1, 1)])
    flat = _lum(textures.asphalt_texture(_look(wheel_track_wear=0.0), LANE_W))
    flat_ratio = np.mean([flat[_row(0.5 + s * 0.85 / LANE_W, h)].mean() for s in (-1, 1)]) / \
        np.mean([flat[_row(0.5 + s * 1.55 / LANE_W, h)].mean() for s in (-1, 1)])
    assert abs(flat_ratio - 1) < 0.03
    assert (track / beside < 0.92) if wear < 0 else (track / beside > 1.08)


def test_seams_across_are_periodic_on_the_tile():
    look = _look(seam_spacing_m=5.0)
    tiling = textures.road_tiling(look)
    assert tiling.asphalt_m == 15.0 and tiling.asphalt_shift_m == 5.0
    t = _lum(textures.asphalt_texture(look, LANE_W, tiling.asphalt_m))
    cols = t.mean(axis=0)
    w = len(cols)
    expected = np.arange(3) * w / 3                            # seams at x = 0, 5, 10 m of the 15 m tile
    dark = []
    c = cols.copy()
    for _ in range(3):
        k = int(np.argmin(c))
        dark.append(k)
        c[np.arange(k - 20, k + 21) % w] = np.inf
    err = [min(abs(((k - e + w / 2) % w) - w / 2) for e in expected) for k in dark]
    assert max(err) <= 4                                       # within 4 px (6 cm): meander and seam width
    assert cols.min() < cols.mean() - 6
    none = _lum(textures.asphalt_texture(_look(), LANE_W)).mean(axis=0)
    assert none.min() > none.mean() - 6                        # without seams no dark column


def test_patches_change_the_lane():
    plain = textures.asphalt_texture(_look(), LANE_W)
    patched = textures.asphalt_texture(_look(patch_density=60.0), LANE_W)    # ~10 patches per 16 m tile
    blur = lambda t: cv2.blur(_lum(t), (31, 31))               # noqa: E731
    assert (np.abs(blur(patched) - blur(plain)) > 5).mean() > 0.2


def test_marking_wear_shows_asphalt():
    def lost(wear):
        t = textures.marking_texture(_look(marking_wear=wear))
        return (_lum(t) < 150).mean(), t
    fresh, t = lost(0.0)
    assert fresh < 0.01 and np.abs(textures.mean_srgb(t) - textures.PAINT_SRGB).max() < 12
    worn, _ = lost(0.6)
    assert abs(worn - 0.85 * 0.6) < 0.06


def test_grass_is_patchy():
    t = textures.grass_texture(_look())
    coarse = cv2.resize(t.astype(np.float32), (32, 8), interpolation=cv2.INTER_AREA)
    chroma = coarse[..., 0] / coarse[..., 1]                   # red / green: straw against green
    assert chroma.max() - chroma.min() > 0.08 and _lum(coarse).std() > 3


def test_vertex_colours_times_texel_is_the_shaded_texel():
    rng = np.random.default_rng(1)
    texels = rng.uniform(20, 150, (50, 3))
    normals = rng.normal(size=(50, 3)) + [0, 0, 3]
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    light = np.array([0.3, -0.4, -0.85])
    albedo = texels.mean(axis=0)
    shaded = shading.shade(np.broadcast_to(albedo, (50, 3)), normals, light, 2.5)
    vc = textures.vertex_rgb(shaded, albedo)
    assert vc.max() > 1.0                                       # the sunlit faces: above 1, not clipped
    assert np.allclose(texels / 255 * vc, shading.shade(texels, normals, light, 2.5), atol=1e-9)


# --------------------------------------------------------------------- texture coordinates
def _road(**kw):
    road_kw = {"lanes": 3, "lane_width_m": LANE_W, "length_m": 400, **kw}
    return parse_scenario({"name": "t", "seed": 1, "road": road_kw}).road


def test_uv_on_the_same_triangles_straight_level():
    r = _road(length_m=403.7)
    tiling = road.Tiling(asphalt_m=15.0, asphalt_shift_m=5.0)
    uvs = road.road_surface_uv(r, tiling=tiling)
    tms = road.road_trimeshes(r)
    assert uvs.keys() == tms.keys()
    for kind, (tris, uv) in uvs.items():
        assert np.array_equal(tris, tms[kind].vertices[tms[kind].faces]) and uv.shape == tris.shape[:2] + (2,)
    tris, uv = uvs["asphalt"]
    x, y = tris[..., 0], -tris[..., 1]
    assert np.allclose(uv[..., 1], (y + LANE_W / 2) / LANE_W)   # v: integer at lane boundaries
    in_lane = lambda k: np.all((uv[..., 1] >= k) & (uv[..., 1] <= k + 1), axis=1)  # noqa: E731
    inner, odd = in_lane(0) | in_lane(2), in_lane(1)
    # seams at multiples of 5 m of the texture are at multiples of 5 m of the road in every lane,
    # the odd lanes mirrored; every piece (dash gaps too) runs one way or the other
    off = lambda sign, sel=slice(None): np.abs(((sign * uv[sel, :, 0] * 15.0 - x[sel]) + 2.5) % 5.0 - 2.5)  # noqa: E731
    assert np.all(off(1, inner) < 1e-6) and np.all(off(-1, odd) < 1e-6)
    assert np.all((off(1).max(axis=1) < 1e-6) | (off(-1).max(axis=1) < 1e-6))
    # no two lanes run the texture the same way: (direction, phase at x = 0) differ
    maps = set()
    for lane in range(3):
        strip = np.all((uv[..., 1] >= lane) & (uv[..., 1] <= lane + 1), axis=1) & (x.max(axis=1) - x.min(axis=1) > 100)
        u, xs = uv[strip, :, 0].ravel(), x[strip].ravel()
        slope = np.polyfit(xs, u, 1)[0]
        assert abs(abs(slope) - 1 / 15.0) < 1e-9
        assert np.sign(slope) == (-1 if lane % 2 else 1)
        maps.add((np.sign(slope), round(float(u[np.argmin(xs)] % 1.0), 6)))
    assert len(maps) == 3
    tris, uv = uvs["grass"]
    assert np.allclose(uv[..., 0], tris[..., 0] / 16.0) and np.allclose(uv[..., 1], -tris[..., 1] / 4.0)


def test_uv_from_the_road_frame_on_a_curve_and_grade():
    r = _road(curves=[{"start_m": 30, "radius_m": 300, "direction": "left", "length_m": 60, "transition_m": 30}],
              profile=[{"start_m": 20, "grade": 0.04, "transition_m": 60}])
    plan, profile = road_plan(r.curves, 0.0), road_profile(r.profile, 0.0)
    uvs = road.road_surface_uv(r, profile, plan)
    tms = road.road_trimeshes(r, profile, plan)
    for kind, (tris, uv) in uvs.items():
        assert np.array_equal(tris, tms[kind].vertices[tms[kind].faces])
    for kind in ("asphalt", "marking"):
        tris, uv = uvs[kind]
        near = np.abs(tris[..., 0] - 300).max(axis=1) < 150     # around the curve
        p = tris[near].reshape(-1, 3)
        x, y = plan.from_plane(np.stack([p[:, 0], -p[:, 1]], -1))
        x, y = x.reshape(-1, 3), y.reshape(-1, 3)
        if kind == "asphalt":
            assert np.allclose(uv[near, :, 1], (y + LANE_W / 2) / LANE_W, atol=1e-6)   # lanes keep their v
            assert np.allclose(np.abs(np.diff(uv[near, :, 0], axis=1)) * 16.0, np.abs(np.diff(x, axis=1)), atol=1e-6)
        else:
            assert np.allclose(uv[near, :, 1] * 0.5, y, atol=1e-6) and np.allclose(uv[near, :, 0] * 4.0, x, atol=1e-6)


# --------------------------------------------------------------------------- textured draws
@contextlib.contextmanager
def _offscreen(width: int, height: int):
    pr = pyrender.OffscreenRenderer(width, height)
    rmod._live_renderers += 1
    try:
        pr._platform.make_current()
        yield pr
    finally:
        rmod._release(pr)


def _add(scene: pyrender.Scene, mesh: pyrender.Mesh) -> None:
    """Add with the insertion order passes.sorted_mesh_nodes breaks ties by."""
    scene.add(mesh)._draw_order = len(scene.mesh_nodes)


def _pyrender_order(inner, scene):
    poses = {n: scene.get_pose(n) for n in scene.mesh_nodes}
    poses[scene.main_camera_node] = scene.get_pose(scene.main_camera_node)
    return passes.sorted_mesh_nodes(scene, poses)


def _dashcam_scene(look: SurfaceLook, width: int, height: int) -> pyrender.Scene:
    """The textured road of a 3-lane motorway and one flat-shaded box, seen from 1.3 m in lane 1."""
    r = _road(markings={"width_m": 0.3})
    scene = pyrender.Scene(bg_color=(*shading.SKY_RGB, 1.0), ambient_light=(0.0, 0.0, 0.0))
    tex = textures.road_textures(look, LANE_W)
    light = np.array([0.4, 0.3, -0.8])
    for kind, (tris, uv) in road.road_surface_uv(r, tiling=textures.road_tiling(look)).items():
        albedo = textures.mean_srgb(tex[kind])
        normals = np.broadcast_to([0.0, 0.0, 1.0], (len(tris), 3))
        vc = textures.vertex_rgb(shading.shade(np.broadcast_to(albedo, (len(tris), 3)), normals, light, 2.8), albedo)
        _add(scene, textures.textured_mesh(tris, uv, vc, tex[kind]))
    box = trimesh.creation.box((4.5, 1.8, 1.5))
    box.apply_translation((30.0, -LANE_W, 0.75))
    rgba = np.tile([0.6, 0.1, 0.1, 1.0], (3 * len(box.faces), 1))
    flat = pyrender.Primitive(positions=box.vertices[box.faces].reshape(-1, 3).astype(np.float32), color_0=rgba,
                              material=pyrender.MetallicRoughnessMaterial(baseColorFactor=(1.0, 1.0, 1.0, 1.0)))
    _add(scene, pyrender.Mesh([flat]))
    f = width / 2 / math.tan(math.radians(35))
    cam = pyrender.IntrinsicsCamera(f, f, width / 2, height / 2, znear=0.05, zfar=6000.0)
    pose = np.eye(4)
    pose[:3, :3] = np.array([[0, 0, -1], [-1, 0, 0], [0, 1, 0]], float)   # looks along +X, image right = -Y
    pose[:3, 3] = (5.0, -LANE_W, 1.3)
    scene.add(cam, pose=pose)
    return scene


def test_textured_colour_pass_is_pyrenders_flat_render():
    look = _look(seam_spacing_m=15.0, patch_density=3.0, wheel_track_wear=-0.4)
    with _offscreen(320, 180) as pr:
        scene = _dashcam_scene(look, 320, 180)
        p = passes.Passes(pr)
        p.update(scene)
        bgr, _ = p.colour(scene, 320, 180)
        assert len(pr._renderer._mesh_textures) == 4
        pr._renderer._sorted_mesh_nodes = types.MethodType(_pyrender_order, pr._renderer)
        rgb, _ = pr.render(scene, flags=pyrender.RenderFlags.FLAT)
        p.delete()
    assert np.array_equal(bgr, rgb[..., ::-1])
    road_rows = bgr[120:, :, 1].astype(float)
    assert road_rows.std() > 4                                 # textured, not flat: grain near the car
    assert bgr[90:110, 150:170, 2].mean() > 100                 # the flat red box is drawn too


def test_texture_orientation_and_vertex_colour_product():
    """Top-down orthographic view of one quad u = X / 4, v = Y / 2 with a 2 x 2 block texture: the
    texel at (u, v) is row H - 1 - floor(v H), column floor(u W); vertex colours multiply it, above 1 too."""
    blocks = np.array([[[200, 20, 20], [20, 200, 20]], [[20, 20, 200], [100, 100, 100]]], np.uint8)
    tex = np.repeat(np.repeat(blocks, 32, axis=0), 32, axis=1)                          # (64, 64, 3)
    quad = np.array([[[0, 0, 0], [4, 0, 0], [4, 2, 0]], [[0, 0, 0], [4, 2, 0], [0, 2, 0]]], float)
    uv = quad[..., :2] / [4.0, 2.0]
    out = {}
    with _offscreen(128, 64) as pr:
        p = passes.Passes(pr, max_anisotropy=4.0)
        for gain in (1.0, 0.5, 1.5):
            scene = pyrender.Scene(bg_color=(0.0, 0.0, 0.0, 1.0), ambient_light=(0.0, 0.0, 0.0))
            _add(scene, textures.textured_mesh(quad, uv, np.full((2, 3), gain), tex))
            pose = np.eye(4)
            pose[:3, 3] = (2.0, 1.0, 10.0)
            scene.add(pyrender.OrthographicCamera(xmag=2.0, ymag=1.0, znear=0.1, zfar=100.0), pose=pose)
            p.update(scene)
            out[gain] = p.colour(scene, 128, 64)[0][..., ::-1].astype(int)                # RGB, top row first
        texture = next(iter(pr._renderer._mesh_textures))
        texture._bind()
        aniso = float(GL.glGetTexParameterfv(GL.GL_TEXTURE_2D, passes.GL_TEXTURE_MAX_ANISOTROPY))
        p.delete()
    assert aniso == 4.0
    for (X, Y), colour in (((1, 1.5), blocks[0, 0]), ((3, 1.5), blocks[0, 1]), ((1, 0.5), blocks[1, 0]),
                           ((3, 0.5), blocks[1, 1])):
        c, r = int(X / 4 * 128), int((2 - Y) / 2 * 64)                                    # image: up = +Y
        assert np.array_equal(out[1.0][r, c], colour)
        assert np.abs(out[0.5][r, c] - colour * 0.5).max() <= 1
        assert np.abs(out[1.5][r, c] - np.minimum(colour * 1.5, 255)).max() <= 1

