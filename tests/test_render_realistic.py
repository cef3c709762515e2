"""The realistic look through the renderer: determinism, exact truth (the id mask inside the 3-D boxes
cv2.projectPoints gives, roadside occluders hiding vehicles in the id mask and counted by visibility),
the simple look untouched, the CLI's --look options."""

from __future__ import annotations

import argparse

import cv2
import numpy as np
import pyrender
import pytest
import trimesh

from harness.commands.look_args import add_look_arguments, apply_look
from harness.render import visibility
from harness.render.realistic import OCCLUDER_CODE, flat_mesh
from harness.render.renderer import Renderer, _add_mesh
from harness.world.scenario import ScenarioError, parse_scenario
from harness.world.state import VehicleState, WorldState
from harness.world.vehicles import vehicle_height

LANE_W = 3.6


def _scenario(look="realistic", seed=5, **render):
    return parse_scenario({
        "name": "real", "seed": seed,
        "road": {"lanes": 3, "lane_width_m": LANE_W, "length_m": 600.0},
        "camera": {"width": 320, "height": 180, "hfov_deg": 70, "height_m": 1.4, "pitch_deg": 1.0},
        "render": {"look": look, **render},
    })


EGO = VehicleState(0, 100.0, LANE_W, 0.0, 25.0, 25.0, 0.0, 1, 5.0, 2.0)
CARS = (VehicleState(1, 118.0, LANE_W, 0.0, 20.0, 20.0, 0.0, 1, 4.6, 1.9),
        VehicleState(2, 130.0, 0.0, 0.0, 22.0, 22.0, 0.0, 0, 4.4, 1.8),
        VehicleState(3, 150.0, 2 * LANE_W, 0.0, 22.0, 22.0, 0.0, 2, 12.0, 2.5))


def _world(vehicles=CARS, frame=3):
    return WorldState(frame, frame / 15, EGO, tuple(vehicles))


@pytest.fixture(scope="module")
def renderer():
    with Renderer(_scenario()) as r:
        yield r


def test_realistic_frames_are_deterministic_and_differ_from_the_simple_look(renderer):
    a = renderer.render(_world())
    with Renderer(_scenario()) as other:
        b = other.render(_world())
    assert a.image.tobytes() == b.image.tobytes()
    assert np.array_equal(a.id_mask, b.id_mask)
    with Renderer(_scenario("simple")) as simple:
        s = simple.render(_world())
    assert a.image.shape == s.image.shape and np.abs(a.image.astype(int) - s.image).mean() > 10
    with Renderer(_scenario(look_seed=6)) as other_look:
        c = other_look.render(_world())
    assert np.abs(a.image.astype(int) - c.image).mean() > 3            # another look seed, another world


def test_id_mask_lies_inside_each_vehicles_projected_box(renderer):
    f = renderer.render(_world())
    cam = renderer.frame_camera
    assert set(np.unique(f.id_mask)) <= {-1, 1, 2, 3}
    for v in CARS:
        ys, xs = np.nonzero(f.id_mask == v.id)
        assert len(xs) > 20
        # the 3-D box corners in the camera model's ego frame (x right, y forward, z up from the camera), by OpenCV
        h, hl, hw = vehicle_height(v.length, v.width), v.length / 2, v.width / 2
        right, ahead = v.y - EGO.y, v.x - (EGO.x + cam.forward_offset_m)
        corners = np.array([[right + sy * hw, ahead + sx * hl, z - cam.height_m]
                            for sx in (-1, 1) for sy in (-1, 1) for z in (0.0, h)])
        uv, _ = cv2.projectPoints(cam.ego_to_cam(corners).reshape(-1, 1, 3), np.zeros(3), np.zeros(3), cam.K, None)
        uv = uv.reshape(-1, 2)
        assert xs.min() >= uv[:, 0].min() - 1 and xs.max() <= uv[:, 0].max() + 1
        assert ys.min() >= uv[:, 1].min() - 1 and ys.max() <= uv[:, 1].max() + 1


def test_a_roadside_occluder_hides_a_vehicle_in_the_id_mask_and_its_visibility():
    with Renderer(_scenario()) as r:
        lead = CARS[0]
        clear = r.render(_world((lead,)))
        # a 3 m wide, 4 m tall board 5 m in front of the lead car, registered as a roadside occluder
        board = trimesh.creation.box(extents=(0.2, 3.0, 4.0))
        board.apply_translation((lead.x - lead.length / 2 - 5.0, -lead.y, 2.0))
        tri = board.vertices[board.faces]
        node = _add_mesh(r._scene, flat_mesh(tri, np.full((len(tri), 3), 0.5), r._material))
        r._real.occluder_nodes.append(node)
        hidden = r.render(_world((lead,)))
    n_clear = int((clear.id_mask == lead.id).sum())
    n_hidden = int((hidden.id_mask == lead.id).sum())
    assert n_clear > 200 and n_hidden < 0.2 * n_clear
    assert not (hidden.id_mask == OCCLUDER_CODE - 1).any()
    # the unoccluded count is the clear frame's, so visibility falls as the pixels do
    assert hidden.full_pixels[lead.id] == pytest.approx(clear.full_pixels[lead.id], rel=0.02) if n_hidden else True
    assert clear.full_pixels[lead.id] == pytest.approx(n_clear, rel=0.02)
    assert clear.full_pixels[lead.id] == pytest.approx(n_clear, rel=0.02)


def test_an_occluder_behind_every_vehicle_leaves_the_truth_unchanged():
    """Occluders wholly farther than every drawn vehicle are left out of the id pass: a board 20 m behind the
    lead car changes its image but neither its id mask nor its counts."""
    with Renderer(_scenario()) as r:
        lead = CARS[0]
        clear = r.render(_world((lead,)))
        board = trimesh.creation.box(extents=(0.2, 12.0, 8.0))
        board.apply_translation((lead.x + lead.length / 2 + 20.0, -lead.y, 4.0))
        tri = board.vertices[board.faces]
        node = _add_mesh(r._scene, flat_mesh(tri, np.full((len(tri), 3), 0.5), r._material))
        r._real.occluder_nodes.append(node)
        behind = r.render(_world((lead,)))
        kept_behind, kept_beyond = r._occluders_in_front(25.0), r._occluders_in_front(45.0)   # lead ~20 m, board ~40 m
    assert node not in kept_behind and node in kept_beyond
    assert np.abs(behind.image.astype(int) - clear.image).sum() > 0
    assert np.array_equal(behind.id_mask, clear.id_mask) and behind.full_pixels == clear.full_pixels


def test_boxes_touching_matches_brute_force():
    rng = np.random.default_rng(0)
    mask = rng.uniform(size=(40, 60)) > 0.995
    boxes = np.c_[rng.uniform(-10, 60, (50, 2)), rng.uniform(0, 25, (50, 2))]
    boxes = np.c_[boxes[:, 0], boxes[:, 2] - 5, boxes[:, 0] + boxes[:, 1] / 3, boxes[:, 2] + boxes[:, 3]]
    got = visibility.boxes_touching(mask, boxes)
    for b, g in zip(boxes, got):
        x0, y0 = max(int(np.floor(b[0] + 0.5)), 0), max(int(np.floor(b[1] + 0.5)), 0)
        x1, y1 = min(int(np.floor(b[2] + 0.5)) + 1, 60), min(int(np.floor(b[3] + 0.5)) + 1, 40)
        want = x1 > x0 and y1 > y0 and bool(mask[y0:y1, x0:x1].any())
        assert g == want


def test_realistic_look_refuses_night():
    with pytest.raises(ScenarioError, match="daylight look"):
        parse_scenario({"name": "n", "render": {"look": "realistic"}, "conditions": {"time_of_day": "night"}})


def test_look_options_set_the_scenarios_render_block():
    p = argparse.ArgumentParser()
    add_look_arguments(p)
    sc = _scenario("simple")
    assert apply_look(sc, p.parse_args([])) is sc
    got = apply_look(sc, p.parse_args(["--look", "realistic", "--look-family", "heldout", "--look-seed", "9"]))
    assert (got.render.look, got.render.look_family, got.render.look_seed) == ("realistic", "heldout", 9)
    with pytest.raises(SystemExit):
        p.parse_args(["--look", "shiny"])


def test_dome_follows_the_camera_and_far_cells_are_not_drawn(renderer):
    renderer.render(_world())
    real = renderer._real
    cam = renderer._scene.get_pose(renderer._cam_node)
    for node in real.dome_nodes:
        np.testing.assert_allclose(renderer._scene.get_pose(node)[:3, 3], cam[:3, 3])
    eye = cam[:2, 3]
    for node, centre in real._cells:
        behind = (centre - eye) @ -cam[:2, 2] < -100
        if behind:
            assert not node.mesh.is_visible
    assert any(n.mesh.is_visible for n, _ in real._cells) or not real._cells
    assert all(isinstance(n.mesh, pyrender.Mesh) for n in real.dome_nodes) and len(real.dome_nodes) > 1


def test_far_vehicles_use_the_simple_mesh_with_hysteresis():
    near, far = (VehicleState(1, 130.0, LANE_W, 0.0, 20.0, 20.0, 0.0, 1, 4.6, 1.9),
                 VehicleState(1, 190.0, LANE_W, 0.0, 20.0, 20.0, 0.0, 1, 4.6, 1.9))
    between = VehicleState(1, 160.5, LANE_W, 0.0, 20.0, 20.0, 0.0, 1, 4.6, 1.9)     # 60 m from the camera
    with Renderer(_scenario()) as r:
        tris = []
        for v in (near, between, far, between, near):
            frame = r.render(_world((v,)))
            tris.append(len(r._vehicles[1].triangles))
            assert (frame.id_mask == 1).any()
    detailed, simple = tris[0], tris[2]
    assert simple < detailed / 3
    assert tris == [detailed, detailed, simple, simple, detailed]     # 60 m keeps whichever it had
