"""The whole roadside of the realistic look: a motorway's verge furniture (:mod:`harness.render.roadside`)
or a street's kerbs and frontage (:mod:`harness.render.street`), the far set and the shadows, as static
geometry in the world frame W (X along the road, Y left, Z up; m). The two builders share roadside.py's
primitives; this module chooses between them."""

from __future__ import annotations

import numpy as np

from harness.render import street as street_mod
from harness.render.look import RoadsideLook, StreetLook, sample_street
from harness.render.roadside import (CLEAR_MARGIN_M, MARGIN_M, Ground, RoadsideGeometry, Batch, bush_batches,
                                     building_batches, faces_of, gantry_batches, hill_batches, Layout, median_batches, pole_batches, rail_batches,
                                     sign_batches, tree_batches, clear_band, ground_shadows)
from harness.world.road_plan import RoadPlan
from harness.world.road_profile import RoadProfile
from harness.world.scenario import Road

STREET_TREES_BEYOND_M = 15.0
"""On a street, the verge's trees and bushes stand at least this far (m) beyond the pavement: behind the frontage."""


def _motorway(ground: Ground, road: Road, lay: Layout, gen, look: RoadsideLook) -> list[Batch]:
    """The verge's occluders: rail, median, trees, bushes, poles, signs, gantries."""
    occ: list[Batch] = []
    right_min_d = 0.2
    if look.guard_rail:
        occ += rail_batches(ground, lay, gen(1), -1, "rail", 0.25)
        right_min_d = 1.0
    occ += median_batches(ground, lay, gen(2), look.median)
    occ += tree_batches(ground, lay, gen(3), look, right_min_d + 0.5)
    occ += bush_batches(ground, lay, gen(4), look, right_min_d + 0.3)
    occ += pole_batches(ground, lay, gen(5), look.pole_spacing_m)
    occ += sign_batches(ground, lay, gen(6), look.sign_density, right_min_d)
    occ += gantry_batches(ground, lay, gen(7), look.gantry_spacing_m, road.lanes, road.lane_width_m)
    return occ


def _street(ground: Ground, road: Road, lay: Layout, gen, look: RoadsideLook,
            street: StreetLook | None) -> tuple[list[Batch], list[np.ndarray]]:
    """A street's occluders (kerbs, frontage, street furniture; the verge's trees and bushes
    :data:`STREET_TREES_BEYOND_M` behind the pavements) and the point sets that cast shadows."""
    frontage = street_mod.frontage_d(road.street)
    behind = frontage + STREET_TREES_BEYOND_M
    back = Layout(lay.x0, lay.x1, lay.edge_left + behind, lay.edge_right - behind, 0.0,
                   max(lay.max_offset - behind, 5.0))
    verge = tree_batches(ground, back, gen(3), look, 0.0) + bush_batches(ground, back, gen(4), look, 0.0)
    occ, parts = street_mod.street_geometry(ground, road, lay, street or sample_street(look.layout_seed))
    return verge + occ, parts + [v for b in verge for v in b.verts]


def roadside_geometry(road: Road, profile: RoadProfile | None, plan: RoadPlan | None, look: RoadsideLook,
                      sun_w: np.ndarray, street: StreetLook | None = None) -> RoadsideGeometry:
    """Everything beside ``road`` for ``look``, following ``profile`` and ``plan`` (None: level,
    straight), with the shadows of the occluders for light travelling along ``sun_w`` (unit, W).
    With ``road.street`` the frontage of ``street`` (default: :func:`sample_street` of the layout
    seed) replaces the verge's furniture."""
    ground = Ground(profile, plan, (-MARGIN_M, road.length_m + MARGIN_M))
    band_lo, band_hi = clear_band(road)
    max_offset = 120.0 if plan is None else min(120.0, 0.5 * plan.min_radius() - 1.0)
    lay = Layout(-MARGIN_M, road.length_m + MARGIN_M, -band_lo, -band_hi,
                  road.shoulder_width_m + (CLEAR_MARGIN_M if road.street is None else 0.0), max(max_offset, 5.0))

    def gen(tag: int) -> np.random.Generator:
        return np.random.default_rng([int(look.layout_seed) & 0xFFFFFFFF, 0x5EED, tag])

    if road.street is None:
        occ = _motorway(ground, road, lay, gen, look)
        parts = [v for b in occ for v in b.verts]
    else:
        occ, parts = _street(ground, road, lay, gen, look, street)
    far = building_batches(ground, road, lay, gen(8), look.building_density) + hill_batches(ground, road, lay, gen(9),
                                                                                 look.hill_height_m)
    shadows = ground_shadows(parts, sun_w, ground)
    return RoadsideGeometry(faces_of(occ), faces_of(far), shadows)
