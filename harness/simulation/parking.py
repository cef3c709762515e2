"""The parked cars of a street (scenario ``road.street``): static vehicles on the parking strips.

A street's shoulders are parking strips (``road.shoulder_width_m`` beyond the outer edge lines, each ending
at a kerb). Along each strip that ``street.parking`` names, cars stand one behind the other: each one's body
type drawn from the cars and small vans of a residential street (:data:`PARKED_SHARES`) and its footprint
from the type's real dimensions (:func:`harness.world.fleet.typical_dimensions`), a gap before the next
drawn so that the strip holds ``street.parked_per_100m`` cars per 100 m on average (an exponential gap:
some cars nose to tail, some driveways' worth of space). A car stands ``KERB_GAP_M`` from the kerb (less
where the strip is narrow), parallel to it within a degree or two (less where that would not fit); it faces its side's direction of travel (right strip: +x; left
strip: -x, the other carriageway's way) with probability ``street.facing_traffic_share``. With
``street.bay_angle_deg`` (30-90) they stand side by side in angled or perpendicular bays instead (:func:`_bays`).

They are not highway-env vehicles: traffic does not see them (it keeps to its lanes, they to the strips),
and nothing moves them. They join each frame's :class:`WorldState` as vehicles (ids from
:data:`PARKED_ID_BASE`, speed 0, lane -1 on the left strip and ``road.lanes`` on the right), so the
renderer draws them and the ground truth boxes them like any other; only those whose centre lies from
:data:`WINDOW_BEHIND_M` behind to :data:`WINDOW_AHEAD_M` ahead of the ego's centre are in a frame.
The road frame is highway-env's: ``x`` along the road, ``y`` to the right, lane 0's centre at y = 0 (m).
"""

from __future__ import annotations

import numpy as np

from harness.world.fleet import typical_dimensions
from harness.world.scenario import Road
from harness.world.state import VehicleState

#: Share of each body type among parked cars (sums to 1): the car shares of the fleet (harness.world.fleet)
#: with small vans; no trucks, buses or pickups on a residential street.
PARKED_SHARES = {"hatchback": 0.36, "saloon": 0.14, "estate": 0.14, "suv": 0.28, "van": 0.08}
#: Id of the first parked car; the left strip's ids follow the right strip's from PARKED_ID_BASE + 50,000.
PARKED_ID_BASE = 100_000
#: Gap between a parked car's kerb-side mirror and the kerb (m), and the spread of that gap (m).
KERB_GAP_M, KERB_GAP_SD_M = 0.25, 0.08
#: Standard deviation of a parked car's heading about the kerb's (deg), and its bound.
YAW_SD_DEG, YAW_MAX_DEG = 1.2, 4.0
#: What a parked car leaves free between itself and the strip's lane-side edge line at least (m).
STRIP_MARGIN_M = 0.02
#: Shortest gap between two parked cars (m).
MIN_GAP_M = 0.6
#: A frame holds the parked cars whose centre is this far behind (m) to this far ahead of the ego's centre.
WINDOW_BEHIND_M, WINDOW_AHEAD_M = 15.0, 300.0
_TAG = 0x9A2C

assert abs(sum(PARKED_SHARES.values()) - 1.0) < 1e-12


def _strip(road: Road, side: int) -> tuple[float, int]:
    """(road-frame y of the kerb (m), lane index) of the right (``side`` +1) or left (-1) parking strip."""
    lw = road.lane_width_m
    if side > 0:
        return (road.lanes - 0.5) * lw + road.shoulder_width_m, road.lanes
    return -0.5 * lw - road.shoulder_width_m, -1


def parked_cars(road: Road, seed: int, x0: float, x1: float) -> tuple[VehicleState, ...]:
    """Every parked car of ``road.street`` whose footprint lies in road ``x`` from ``x0`` to ``x1`` (m),
    for the scenario ``seed`` (deterministic; independent of the traffic's draws). Empty without a street."""
    street = road.street
    if street is None or street.parking == "none" or street.parked_per_100m <= 0:
        return ()
    bodies = tuple(PARKED_SHARES)
    p = np.array([PARKED_SHARES[b] for b in bodies])
    mean_length = 4.5
    mean_gap = max(100.0 / street.parked_per_100m - mean_length, MIN_GAP_M)
    out: list[VehicleState] = []
    for side in ((1,) if street.parking == "right" else (1, -1)):
        rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, _TAG, side > 0])
        y_kerb, lane = _strip(road, side)
        vid = PARKED_ID_BASE + (0 if side > 0 else 50_000)
        if street.bay_angle_deg > 0.0:
            out.extend(_bays(road, side, rng, x0, x1, vid, bodies, p))
            continue
        x = x0 + float(rng.exponential(mean_gap))
        while True:
            body = bodies[int(rng.choice(len(bodies), p=p))]
            length, width = typical_dimensions(body, rng)
            if x + length > x1:
                break
            gap = float(np.clip(rng.normal(KERB_GAP_M, KERB_GAP_SD_M), 0.05, 0.5))
            forward = rng.uniform() < street.facing_traffic_share
            yaw = np.radians(float(np.clip(rng.normal(0.0, YAW_SD_DEG), -YAW_MAX_DEG, YAW_MAX_DEG)))
            room = road.shoulder_width_m - STRIP_MARGIN_M       # what the car, turned by yaw, and its gap may take
            while yaw and length * abs(np.sin(yaw)) + width * np.cos(yaw) > room - 0.05:
                yaw *= 0.5 if abs(yaw) > 1e-3 else 0.0
            across = length * abs(np.sin(yaw)) + width * np.cos(yaw)
            gap = min(gap, max(room - across, 0.0))
            y = y_kerb - side * (gap + across / 2)
            heading = (0.0 if forward else np.pi) if side > 0 else (np.pi if forward else 0.0)
            heading += yaw
            out.append(VehicleState(id=vid, x=round(x + length / 2, 3), y=round(y, 3), heading=float(heading),
                                    speed=0.0, vx=0.0, vy=0.0, lane=lane, length=length, width=width,
                                    name=None, body=body))
            vid += 1
            x += length + MIN_GAP_M + float(rng.exponential(max(mean_gap - MIN_GAP_M, 0.01)))
    return tuple(out)


def _bays(road: Road, side: int, rng: np.random.Generator, x0: float, x1: float, vid: int,
          bodies: tuple[str, ...], p: np.ndarray) -> list[VehicleState]:
    """The cars of one strip of angled or perpendicular bays (``street.bay_angle_deg``): side by side, each
    long axis at the bay angle to the kerb (leaning with the side's direction of travel), nose to the kerb
    with probability ``street.facing_traffic_share`` (else reversed in), ``KERB_GAP_M`` from it. Each car
    stands clear of the one before across its own short axis (separating-axis spacing along the strip:
    ``dx = (sep + dy cos a) / sin a``), by ``MIN_GAP_M`` plus an exponential share of the density's pitch.
    A body too long for the strip's depth at the angle is not parked (the bay stays empty)."""
    street = road.street
    y_kerb, lane = _strip(road, side)
    a = np.radians(street.bay_angle_deg)
    sin_a, cos_a = np.sin(a), np.cos(a)
    room = road.shoulder_width_m - STRIP_MARGIN_M
    pitch = 100.0 / street.parked_per_100m                     # mean along-strip spacing (m)
    extra = max(pitch - (1.8 + MIN_GAP_M) / sin_a, 0.01)       # beyond a typical car's tightest spacing
    out: list[VehicleState] = []
    x = x0 + 3.0                                               # the next bay's earliest centre (m)
    prev: tuple[float, float, float] | None = None             # (x, y, width) of the car before
    while x < x1:
        body = bodies[int(rng.choice(len(bodies), p=p))]
        length, width = typical_dimensions(body, rng)
        gap = float(np.clip(rng.normal(KERB_GAP_M, KERB_GAP_SD_M), 0.05, 0.5))
        nose_in = rng.uniform() < street.facing_traffic_share
        yaw = np.radians(float(np.clip(rng.normal(0.0, YAW_SD_DEG), -YAW_MAX_DEG, YAW_MAX_DEG)))
        space = float(rng.exponential(extra))
        h = a + yaw
        across = length * abs(np.sin(h)) + width * abs(np.cos(h))
        if across > room - 0.05:                               # too long for the strip: an empty bay
            x += space + (width + MIN_GAP_M) / sin_a
            continue
        gap = min(gap, room - across)
        y = y_kerb - side * (gap + across / 2)
        x += space
        if prev is not None:                                   # clear of the car before across its short axis
            px, py, pw = prev
            x = max(x, px + ((pw + width) / 2 + MIN_GAP_M + (y - py) * cos_a) / sin_a + space)
        if x + length * abs(np.cos(h)) / 2 + width * sin_a / 2 > x1:
            break
        # the axis leans with the side's travel: right strip +x and towards the kerb (+y), left strip -x, -y
        heading = h if side > 0 else h + np.pi
        if not nose_in:
            heading += np.pi
        heading = float(np.arctan2(np.sin(heading), np.cos(heading)))
        out.append(VehicleState(id=vid, x=round(float(x), 3), y=round(float(y), 3), heading=heading, speed=0.0,
                                vx=0.0, vy=0.0, lane=lane, length=length, width=width, name=None, body=body))
        vid += 1
        prev = (x, y, width)
    return out


class ParkedCars:
    """A scenario's parked cars, laid out once; :meth:`near` gives those of one frame."""

    def __init__(self, road: Road, seed: int) -> None:
        self.cars = parked_cars(road, seed, 0.0, road.length_m)
        self._x = np.array([c.x for c in self.cars], float)

    def near(self, ego_x: float) -> tuple[VehicleState, ...]:
        """The parked cars whose centre lies within the frame window around the ego's centre ``ego_x`` (m)."""
        if not self.cars:
            return ()
        keep = np.flatnonzero((self._x >= ego_x - WINDOW_BEHIND_M) & (self._x <= ego_x + WINDOW_AHEAD_M))
        return tuple(self.cars[i] for i in keep)
