"""The scenario's vehicles as highway-env vehicles.

* :class:`ScenarioVehicle` — an ``IDMVehicle`` whose longitudinal control is a
  swappable :class:`Longitudinal` controller (highway-env's IDM, a cruise
  control, a scripted brake) and which starts timed events
  (:mod:`harness.simulation.events`) when their time comes;
* :class:`StationaryVehicle` — a parked vehicle: a highway-env ``Obstacle``
  (never moves, never pushed by collisions; IDM/MOBIL vehicles react to it).

Units: m, s, m/s, m/s^2. Time comes from a shared :class:`Clock` (frame count / fps).
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
from highway_env.road.road import LaneIndex, Road
from highway_env.vehicle.behavior import IDMVehicle
from highway_env.vehicle.kinematics import Vehicle
from highway_env.vehicle.objects import Obstacle

from harness.world import scenario as sc


class VehicleEvent(Protocol):
    """What a vehicle asks of its timed events (:class:`harness.simulation.events.TimedEvent` is one)."""

    def due(self, t: float) -> bool: ...

    def start(self, vehicle: "ScenarioVehicle") -> None: ...


MAX_SPEED_MPS = 60.0
"""Speed cap of scenario vehicles (the schema's bound; highway-env's default cap is 40 m/s)."""

CRUISE_RAMP_MPS2 = 2.0
"""Acceleration (m/s^2, both ways) with which a cruise control reaches a new target speed."""


class Clock:
    """Simulation time by frame count: ``t = frame / fps`` exactly, never accumulated."""

    def __init__(self, fps: float) -> None:
        self.fps = float(fps)
        self.dt = 1.0 / self.fps
        self.frame = 0

    @property
    def t(self) -> float:
        return self.frame / self.fps


class Longitudinal(Protocol):
    """A longitudinal controller: the acceleration command (m/s^2) for the next step."""

    def acceleration(self, vehicle: "ScenarioVehicle", dt: float) -> float: ...


class FollowIDM:
    """highway-env's IDM (with MOBIL lane changes where enabled); the vehicle's ``target_speed``."""

    def acceleration(self, vehicle: "ScenarioVehicle", dt: float) -> float:  # pragma: no cover - marker
        raise NotImplementedError("FollowIDM is run by IDMVehicle.act itself")


class Cruise:
    """Constant speed: hold ``target_mps``; reach a new target at ``ramp_mps2`` (exact on the last step)."""

    def __init__(self, target_mps: float, ramp_mps2: float = CRUISE_RAMP_MPS2) -> None:
        self.target_mps = float(target_mps)
        self.ramp_mps2 = float(ramp_mps2)

    def acceleration(self, vehicle: "ScenarioVehicle", dt: float) -> float:
        return float(np.clip((self.target_mps - vehicle.speed) / dt, -self.ramp_mps2, self.ramp_mps2))


class Brake:
    """Decelerate at ``decel_mps2`` until ``until_mps`` (landing on it exactly), then hold that speed."""

    def __init__(self, decel_mps2: float, until_mps: float) -> None:
        self.decel_mps2 = float(decel_mps2)
        self.until_mps = float(until_mps)

    def acceleration(self, vehicle: "ScenarioVehicle", dt: float) -> float:
        if vehicle.speed <= self.until_mps:
            return 0.0
        return max(-self.decel_mps2, (self.until_mps - vehicle.speed) / dt)


class ScenarioVehicle(IDMVehicle):
    """A moving scenario vehicle (ego, placed or traffic) with a stable id.

    ``behaviour`` is ``"idm"`` (highway-env IDM/MOBIL with the given parameters;
    lane changes only if ``lane_changes``) or ``"constant_speed"`` (cruise
    control, keeps its lane). Events replace the longitudinal controller or the
    target lane at their time; see :mod:`harness.simulation.events`.
    """

    def __init__(
        self,
        road: Road,
        position: np.ndarray,
        speed: float,
        *,
        vid: int,
        name: str | None,
        clock: Clock,
        behaviour: str,
        lane_changes: bool,
        idm: sc.IDMParams,
        mobil: sc.MOBILParams,
        length: float = Vehicle.LENGTH,
        width: float = Vehicle.WIDTH,
        body: str | None = None,
    ) -> None:
        # Per-instance size before RoadObject.__init__ derives the collision diagonal from it.
        self.LENGTH = float(length)
        self.WIDTH = float(width)
        self.body = body
        super().__init__(road, position, heading=0.0, speed=float(speed), enable_lane_change=False)
        self.MAX_SPEED = MAX_SPEED_MPS
        self.COMFORT_ACC_MAX = idm.a_max
        self.COMFORT_ACC_MIN = -idm.b_comfort
        self.DISTANCE_WANTED = idm.distance_wanted_m
        self.TIME_WANTED = idm.time_wanted_s
        self.DELTA = idm.delta
        self.POLITENESS = mobil.politeness
        self.LANE_CHANGE_MIN_ACC_GAIN = mobil.min_acc_gain
        self.LANE_CHANGE_MAX_BRAKING_IMPOSED = mobil.max_braking_imposed
        self.LANE_CHANGE_DELAY = mobil.lane_change_delay_s
        # highway-env's deterministic phase of the lane-change timer, with this vehicle's delay.
        delay = self.LANE_CHANGE_DELAY
        self.timer = float(np.sum(self.position) * np.pi) % delay if delay > 0 else 0.0
        self.target_speed = float(speed)
        self.vid = vid
        self.name = name
        self.clock = clock
        self.behaviour = behaviour
        self.lane_changes = bool(lane_changes)
        self.longitudinal: Longitudinal = FollowIDM() if behaviour == "idm" else Cruise(speed)
        self.enable_lane_change = self.lane_changes and behaviour == "idm"
        self.manoeuvre_lane: LaneIndex | None = None   # target of a scripted lane change in progress
        self.events: list[VehicleEvent] = []
        self.lateral_offset_m = 0.0                    # steered offset from the lane centre (m, + right)

    def steering_control(self, target_lane_index: LaneIndex) -> float:
        """highway-env's lane-keeping steering, aiming ``lateral_offset_m`` right of the centre line
        of its current lane (straight roads along +x; road y grows to the right) until a scripted
        lane change starts."""
        if not self.lateral_offset_m or self.manoeuvre_lane is not None:
            return super().steering_control(target_lane_index)
        saved = self.position
        self.position = saved - np.array([0.0, self.lateral_offset_m])
        try:
            return super().steering_control(target_lane_index)
        finally:
            self.position = saved

    # ---------------------------------------------------------------- control
    def act(self, action: dict | str | None = None) -> None:
        """Start due events, then decide steering and acceleration for the next step."""
        if self.crashed:
            return
        while self.events and self.events[0].due(self.clock.t):
            self.events.pop(0).start(self)
        if self.manoeuvre_lane is not None and self.lane_index == self.manoeuvre_lane:
            self.manoeuvre_lane = None                 # scripted lane change done
            self.enable_lane_change = self.lane_changes and isinstance(self.longitudinal, FollowIDM)
        dt = self.clock.dt
        if isinstance(self.longitudinal, FollowIDM):
            super().act()
            acc = self.action["acceleration"]
            acc = max(acc, -self.speed / dt)          # IDM never reverses on a highway
            if self.target_speed <= 0:
                acc = min(acc, 0.0)                    # highway-env's IDM creeps forward at target 0
            self.action["acceleration"] = float(acc)
            return
        self.follow_road()
        steering = float(np.clip(self.steering_control(self.target_lane_index),
                                 -self.MAX_STEERING_ANGLE, self.MAX_STEERING_ANGLE))
        Vehicle.act(self, {"steering": steering, "acceleration": self.longitudinal.acceleration(self, dt)})


class StationaryVehicle(Obstacle):
    """A parked vehicle: speed 0, never moves; an obstacle IDM/MOBIL vehicles react to."""

    def __init__(self, road: Road, position: np.ndarray, *, vid: int, name: str | None,
                 length: float = Vehicle.LENGTH, width: float = Vehicle.WIDTH, body: str | None = None) -> None:
        self.LENGTH = float(length)
        self.WIDTH = float(width)
        self.body = body
        super().__init__(road, position, heading=0.0, speed=0.0)
        self.vid = vid
        self.name = name
