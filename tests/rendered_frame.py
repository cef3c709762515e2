"""Shared by the detector-model tests: one scenario's first frame, rendered, with its ground truth."""

from __future__ import annotations


def first_frame(scenario: dict):
    """``(scenario, image, truth)`` of a scenario dict's first frame (BGR image, :class:`FrameTruth`)."""
    from harness.world.ground_truth import frame_truth
    from harness.render.renderer import Renderer
    from harness.world.scenario import parse_scenario
    from harness.simulation.simulator import simulate

    scen = parse_scenario(scenario)
    with Renderer(scen) as r:
        w = next(iter(simulate(scen, 1)))
        fr = r.render(w)
        return scen, fr.image, frame_truth(w, r.camera, fr.id_mask, fr.full_pixels)
