"""Timed scenario events as small controllers handed to :class:`~harness.simulation.vehicles.ScenarioVehicle`.

An event starts in the vehicle's own ``act`` at the first frame whose time
``frame / fps`` is at or after ``at_s``; it then replaces the vehicle's
longitudinal controller and/or target lane. A later event overrides an
earlier one.

* brake — decelerate at ``decel_mps2`` (overriding IDM) to ``until_speed_mps``, then hold it;
* speed_change — a new target speed: IDM's desired speed, or a cruise control's
  target reached at :data:`~harness.simulation.vehicles.CRUISE_RAMP_MPS2`;
* cut_in — until ``at_s`` the vehicle holds its lane and initial speed; at ``at_s``
  highway-env's lane-change steering takes it into the ego's lane, after which it
  resumes its behaviour.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

from harness.world import scenario as sc
from harness.simulation.vehicles import Brake, Cruise, FollowIDM, ScenarioVehicle

TIME_EPS_S = 1e-9


class TimedEvent(ABC):
    def __init__(self, at_s: float) -> None:
        self.at_s = float(at_s)

    def due(self, t: float) -> bool:
        return t >= self.at_s - TIME_EPS_S

    def prepare(self, vehicle: ScenarioVehicle) -> None:
        """Adjust the vehicle at creation (before t = 0); nothing by default."""

    @abstractmethod
    def start(self, vehicle: ScenarioVehicle) -> None:
        """Take effect at ``at_s``."""


class BrakeStart(TimedEvent):
    def __init__(self, event: sc.BrakeEvent) -> None:
        super().__init__(event.at_s)
        self.decel_mps2 = event.decel_mps2
        self.until_mps = event.until_speed_mps

    def start(self, vehicle: ScenarioVehicle) -> None:
        vehicle.longitudinal = Brake(self.decel_mps2, self.until_mps)
        vehicle.target_speed = self.until_mps
        vehicle.enable_lane_change = False


class SpeedChangeStart(TimedEvent):
    def __init__(self, event: sc.SpeedChangeEvent) -> None:
        super().__init__(event.at_s)
        self.target_mps = event.target_speed_mps

    def start(self, vehicle: ScenarioVehicle) -> None:
        vehicle.target_speed = self.target_mps
        if vehicle.behaviour == "idm":
            vehicle.longitudinal = FollowIDM()
            vehicle.enable_lane_change = vehicle.lane_changes and vehicle.manoeuvre_lane is None
        else:
            vehicle.longitudinal = Cruise(self.target_mps)


class CutInStart(TimedEvent):
    """Steer into the lane the ego is in (or heading for) at ``at_s``."""

    def __init__(self, event: sc.CutInEvent, ego: ScenarioVehicle) -> None:
        super().__init__(event.at_s)
        self.ego = ego

    def prepare(self, vehicle: ScenarioVehicle) -> None:
        vehicle.longitudinal = Cruise(vehicle.speed)
        vehicle.enable_lane_change = False

    def start(self, vehicle: ScenarioVehicle) -> None:
        lane = self.ego.target_lane_index
        vehicle.target_lane_index = lane
        vehicle.manoeuvre_lane = lane
        vehicle.enable_lane_change = False
        if vehicle.behaviour == "idm":
            vehicle.longitudinal = FollowIDM()


def timed_events(events: list[sc.Event], ego: ScenarioVehicle) -> dict[str, list[TimedEvent]]:
    """The scenario's events as controllers, grouped by vehicle name (or ``"ego"``), in time order."""
    out: dict[str, list[TimedEvent]] = {}
    for e in events:
        if isinstance(e, sc.BrakeEvent):
            ev: TimedEvent = BrakeStart(e)
        elif isinstance(e, sc.SpeedChangeEvent):
            ev = SpeedChangeStart(e)
        else:
            ev = CutInStart(e, ego)
        out.setdefault(e.vehicle, []).append(ev)
    for evs in out.values():
        evs.sort(key=lambda ev: ev.at_s)     # stable: equal times keep file order
    return out
