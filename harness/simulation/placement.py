"""Initial placement (t = 0) of the ego, the scenario's placed vehicles and random traffic.

Pure geometry in the road frame (see :mod:`harness.simulation.road`): positions
are vehicle centres, ``x`` along the road (m), ``y`` across it (m).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from harness.world.fleet import draw_body, typical_dimensions, vehicle_rng


TRAFFIC_MIN_GAP_M = 5.0
"""Bumper-to-bumper clearance (m) a random traffic vehicle keeps, at t = 0, to every other vehicle in its lane."""

ROAD_START_MARGIN_M = 5.0
"""No vehicle's rear may start closer than this to the road's start (m)."""


@dataclass(frozen=True)
class Footprint:
    """An axis-aligned vehicle rectangle at t = 0: centre (x, y), length along x, width along y (m)."""

    x: float
    y: float
    length: float
    width: float

    def overlaps(self, other: "Footprint", long_clearance: float = 0.0) -> bool:
        """Whether the rectangles intersect once this one is grown by ``long_clearance`` front and back."""
        return (abs(self.x - other.x) < (self.length + other.length) / 2 + long_clearance
                and abs(self.y - other.y) < (self.width + other.width) / 2)


def placed_centre_x(ego_x: float, camera_forward_offset_m: float, distance_m: float, length_m: float) -> float:
    """Centre ``x`` of a vehicle whose rear face is ``distance_m`` ahead of the camera.

    The camera sits ``camera_forward_offset_m`` ahead of the ego's centre, so the
    rear face is at ``ego_x + offset + distance`` and the centre half a length further.
    """
    return ego_x + camera_forward_offset_m + distance_m + length_m / 2


def cut_in_distance(gap_m: float, at_s: float, vehicle_speed_mps: float, ego_speed_mps: float) -> float:
    """Initial camera-to-rear distance (m) that becomes ``gap_m`` at ``at_s`` if both keep their speeds."""
    return gap_m - (vehicle_speed_mps - ego_speed_mps) * at_s


def create_random_offset(speed_mps: float, spacing: float, lanes: int) -> float:
    """highway-env's ``Vehicle.create_random`` headway (m) before the next vehicle on a ``lanes``-lane road."""
    return spacing * (12.0 + 1.0 * speed_mps) * math.exp(-5.0 / 40.0 * lanes)


@dataclass(frozen=True)
class TrafficSlot:
    lane: int
    x: float          # centre, m
    speed: float      # m/s


def traffic_slots(
    rng: np.random.Generator,
    count: int,
    lanes: int,
    lane_width_m: float,
    density: float,
    speed_range_mps: tuple[float, float],
    occupied: list[Footprint],
    ego_x: float,
    road_length_m: float,
    length_m: float = 5.0,
    width_m: float = 2.0,
    sizes: Sequence[tuple[float, float]] | None = None,
) -> list[TrafficSlot]:
    """Random traffic placed as highway-env's ``create_random(road, speed, spacing=1/density)`` does.

    highway-env places each new vehicle one random headway
    (:func:`create_random_offset` times U(0.9, 1.1)) ahead of the previous one, in a
    random lane. Here the chain starts behind the ego, so that about a third of the
    vehicles are behind it and the rest ahead. A slot whose rectangle (grown by
    :data:`TRAFFIC_MIN_GAP_M` front and back) meets an ``occupied`` one or an earlier
    slot tries the other lanes in random order, then moves one more headway ahead.
    Deterministic for the state of ``rng``. ``sizes``: per vehicle (length, width) (m) instead of
    ``length_m`` x ``width_m`` for all (a mixed fleet, :func:`fleet_sizes`).
    """
    lo, hi = speed_range_mps
    spacing = 1.0 / density
    mean_offset = create_random_offset((lo + hi) / 2, spacing, lanes)
    x = max(ego_x - (count // 3) * mean_offset, length_m / 2 + ROAD_START_MARGIN_M)
    taken = list(occupied)
    slots: list[TrafficSlot] = []
    for k in range(count):
        speed = float(rng.uniform(lo, hi))
        offset = create_random_offset(speed, spacing, lanes)
        if k > 0:
            x += offset * rng.uniform(0.9, 1.1)
        if sizes is not None:
            length_m, width_m = sizes[k]
        while True:
            if x + length_m / 2 > road_length_m:
                raise ValueError(f"only {k} of {count} traffic vehicles fit on the {road_length_m:g} m road")
            free = [int(lane) for lane in rng.permutation(lanes)
                    if not any(Footprint(x, lane * lane_width_m, length_m, width_m).overlaps(f, TRAFFIC_MIN_GAP_M)
                               for f in taken)]
            if free:
                break
            x += offset * rng.uniform(0.9, 1.1)
        lane = free[0]
        taken.append(Footprint(x, lane * lane_width_m, length_m, width_m))
        slots.append(TrafficSlot(lane, float(x), speed))
    return slots


def fleet_sizes(seed: int, first_id: int, count: int) -> list[tuple[str, float, float]]:
    """(body, length m, width m) of the traffic vehicles ``first_id .. first_id + count - 1`` of a mixed fleet,
    each drawn by :func:`harness.world.fleet.draw_body` from its own generator (scenario seed, vehicle id)."""
    return [draw_body(vehicle_rng(seed, first_id + k)) for k in range(count)]


def placed_size(length_m: float | None, width_m: float | None, body: str | None, seed: int,
                vehicle_id: int) -> tuple[float, float]:
    """A placed vehicle's (length, width) in m: those given; those absent drawn from ``body``'s typical
    dimensions (:func:`harness.world.fleet.typical_dimensions`, seeded by the scenario seed and its id)."""
    if length_m is not None and width_m is not None:
        return float(length_m), float(width_m)
    if body is None:
        raise ValueError("a placed vehicle without a body needs length_m and width_m")
    length, width = typical_dimensions(body, vehicle_rng(seed, vehicle_id))
    return (length if length_m is None else float(length_m)), (width if width_m is None else float(width_m))
