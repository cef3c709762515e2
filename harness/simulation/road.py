"""The scenario's straight highway as a highway-env road network.

Road frame (highway-env's): ``x`` along the road from its start (m), ``y`` across
it towards higher lane indices (to the right of travel). Lane 0 is the leftmost
lane with its centre at ``y = 0``; lane ``i`` has its centre at
``y = i * lane_width_m`` — the layout of ``RoadNetwork.straight_road_network``.
"""

from __future__ import annotations

import numpy as np
from highway_env.road.lane import LineType, StraightLane
from highway_env.road.road import Road, RoadNetwork
from highway_env.vehicle.objects import Landmark

from harness.world import scenario as sc

NODES = ("0", "1")
"""Start and end node of the single road segment."""


def lane_centre_y(lane: int, lane_width_m: float) -> float:
    """Road-frame ``y`` (m) of lane ``lane``'s centre line."""
    return lane * lane_width_m


def lane_index(lane: int) -> tuple[str, str, int]:
    """highway-env lane index of absolute lane ``lane``."""
    return (*NODES, lane)


def build_network(road: sc.Road) -> RoadNetwork:
    """One straight segment of ``road.lanes`` parallel lanes, ``length_m`` long.

    Line types as highway-env draws them: a continuous line on the outer edges,
    stripes between lanes (each lane owns its left line; only the rightmost its right one).
    """
    net = RoadNetwork()
    for i in range(road.lanes):
        y = lane_centre_y(i, road.lane_width_m)
        line_types = (
            LineType.CONTINUOUS_LINE if i == 0 else LineType.STRIPED,
            LineType.CONTINUOUS_LINE if i == road.lanes - 1 else LineType.NONE,
        )
        net.add_lane(*NODES, StraightLane(
            np.array([0.0, y]), np.array([road.length_m, y]), width=road.lane_width_m,
            line_types=line_types, speed_limit=road.speed_limit_mps))
    return net


class StraightRoad(Road):
    """highway-env's :class:`Road` with its two O(N^2) loops vectorised, same results.

    * ``neighbour_vehicles`` (IDM's leader / follower search, called once or twice
      per vehicle per step): lane coordinates of every object at once, from a
      snapshot of positions taken when ``act`` starts (``act`` moves nothing).
      Ties are broken as highway-env's loop does (front: last; rear: first).
    * ``step``'s collision loop: highway-env's own circle pre-check of every pair
      at once, then its exact ``handle_collisions`` only for the pairs that pass,
      in highway-env's order.

    Both fall back to highway-env's code for lanes other than straight ones or
    with ``neighbour_vehicles_connected_lanes``.
    """

    PRECHECK_MARGIN_M = 1e-9
    """Widens the pre-check (m) so that rounding never drops a pair highway-env would check."""

    _snapshot: tuple[list, np.ndarray, dict[int, int]] | None = None

    def _objects_snapshot(self) -> tuple[list, np.ndarray, dict[int, int]]:
        objs = [o for o in self.vehicles + self.objects if not isinstance(o, Landmark)]
        pos = np.array([o.position for o in objs], dtype=float).reshape(-1, 2)
        return objs, pos, {id(o): k for k, o in enumerate(objs)}

    def act(self) -> None:
        self._snapshot = self._objects_snapshot()
        try:
            super().act()
        finally:
            self._snapshot = None

    def neighbour_vehicles(self, vehicle, lane_index=None):
        lane_index = lane_index or vehicle.lane_index
        if not lane_index:
            return None, None
        lane = self.network.get_lane(lane_index)
        if self.neighbour_vehicles_connected_lanes or type(lane) is not StraightLane:
            return super().neighbour_vehicles(vehicle, lane_index)
        objs, pos, index = self._snapshot or self._objects_snapshot()
        if not objs:
            return None, None
        s = lane.local_coordinates(vehicle.position)[0]
        delta = pos - lane.start
        s_v = delta @ lane.direction
        lat_v = delta @ lane.direction_lateral
        on = ((np.abs(lat_v) <= lane.width / 2 + 1)
              & (-lane.VEHICLE_LENGTH <= s_v) & (s_v < lane.length + lane.VEHICLE_LENGTH))
        k_self = index.get(id(vehicle))
        if k_self is not None:
            on[k_self] = False
        front = np.flatnonzero(on & (s_v >= s))
        rear = np.flatnonzero(on & (s_v < s))
        v_front = v_rear = None
        if front.size:
            sf = s_v[front]
            v_front = objs[front[np.flatnonzero(sf == sf.min())[-1]]]
        if rear.size:
            sr = s_v[rear]
            v_rear = objs[rear[np.flatnonzero(sr == sr.max())[0]]]
        return v_front, v_rear

    def step(self, dt: float) -> None:
        for vehicle in self.vehicles:
            vehicle.step(dt)
        n = len(self.vehicles)
        if n == 0:
            return
        others = self.vehicles + self.objects
        pos = np.array([o.position for o in others], dtype=float).reshape(-1, 2)
        diag = np.array([o.diagonal for o in others], dtype=float)
        speed = np.array([v.speed for v in self.vehicles], dtype=float)
        dist = np.sqrt(((pos[:n, None, :] - pos[None, :, :]) ** 2).sum(-1))     # (n, n + m)
        reach = (diag[:n, None] + diag[None, :]) / 2 + speed[:, None] * dt + self.PRECHECK_MARGIN_M
        near = dist <= reach
        near[:, :n] &= np.triu(np.ones((n, n), dtype=bool), 1)               # each vehicle pair once, i < j
        for i in np.flatnonzero(near.any(axis=1)):
            for j in np.flatnonzero(near[i]):
                self.vehicles[i].handle_collisions(others[j], dt)


def build_road(road: sc.Road, np_random: np.random.Generator) -> StraightRoad:
    """An empty :class:`StraightRoad` on :func:`build_network`, no trajectory history."""
    return StraightRoad(network=build_network(road), np_random=np_random, record_history=False)
