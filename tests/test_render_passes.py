"""harness.render.passes draws what pyrender's own forward pass draws (colour image and id pass, byte for byte),
and an id pass read from the corner of a larger framebuffer is the one of its own size."""

from __future__ import annotations

import types

import numpy as np
import pyrender
import pytest

from harness.render import passes
from harness.render.renderer import Renderer, _seg_colour
from harness.world.scenario import parse_scenario
from harness.world.state import VehicleState, WorldState

LANE_W = 3.7
EGO = VehicleState(0, 100.0, LANE_W, 0.0, 25.0, 25.0, 0.0, 1, 5.0, 2.0)
CARS = (VehicleState(1, 118.0, LANE_W, 0.0, 20.0, 20.0, 0.0, 1, 4.6, 1.9),
        VehicleState(2, 124.0, 0.0, 0.02, 22.0, 22.0, 0.4, 0, 4.4, 1.8),
        VehicleState(3, 150.0, 2 * LANE_W, 0.0, 22.0, 22.0, 0.0, 2, 12.0, 2.5),
        VehicleState(4, 104.0, 2 * LANE_W, 0.0, 22.0, 22.0, 0.0, 2, 4.5, 1.9))     # cut by the image border


def _scenario(**extra):
    return parse_scenario({"name": "p", "seed": 3, "road": {"lanes": 3, "lane_width_m": LANE_W},
                           "camera": {"width": 320, "height": 180, "hfov_deg": 70}, **extra})


def _pyrender_order(inner, scene):
    """pyrender's draw order made deterministic the way :mod:`harness.render.passes` orders (ties by insertion)."""
    poses = {n: scene.get_pose(n) for n in scene.mesh_nodes}
    poses[scene.main_camera_node] = scene.get_pose(scene.main_camera_node)
    return passes.sorted_mesh_nodes(scene, poses)


@pytest.mark.parametrize("extra", [{}, {"conditions": {"time_of_day": "dusk", "fog_visibility_m": 150.0}}])
def test_passes_match_pyrender(extra):
    with Renderer(_scenario(**extra)) as r:
        frame = r.render(WorldState(3, 0.2, EGO, CARS))
        assert len(np.unique(frame.id_mask)) >= 4                      # three or more cars and the background
        pr, scene = r._pr, r._scene
        pr._renderer._sorted_mesh_nodes = types.MethodType(_pyrender_order, pr._renderer)
        rgb, depth = pr.render(scene, flags=pyrender.RenderFlags.FLAT)
        with r._gl():
            r._passes.update(scene)
            bgr, z = r._passes.colour(scene, 320, 180, want_depth=True)
        assert np.array_equal(bgr, rgb[..., ::-1])
        if not extra:                                                   # no effects: the frame is the colour pass
            assert np.array_equal(frame.image, bgr)
        assert np.array_equal(z > 0.999999, depth == 0)                 # sky: far plane / pyrender's 0
        seg_map = {e.node: _seg_colour(vid + 1) for vid, e in r._vehicles.items() if e.node.mesh.is_visible}
        seg, _ = pr.render(scene, flags=pyrender.RenderFlags.SEG, seg_node_map=seg_map)
        codes = seg[..., 0].astype(np.int32) | seg[..., 1].astype(np.int32) << 8 | seg[..., 2].astype(np.int32) << 16
        assert np.array_equal(frame.id_mask, codes - 1)


def test_id_pass_in_a_grown_framebuffer():
    with Renderer(_scenario()) as r:
        r.render(WorldState(3, 0.2, EGO, CARS))
        scene = r._scene
        seg_map = {e.node: _seg_colour(vid + 1) for vid, e in r._vehicles.items() if e.node.mesh.is_visible}
        with r._gl():
            r._passes.update(scene)
            exact = r._passes.ids(scene, 320, 180, seg_map).copy()
            r._passes.ids(scene, 992, 416, seg_map)                     # grows the framebuffer
            assert r._passes._fbs["ids"].width == 992
            again = r._passes.ids(scene, 320, 180, seg_map)
        assert exact.any() and np.array_equal(exact, again)
