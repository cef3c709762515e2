"""Steps a scenario's highway-env world once per frame and exposes each frame as a :class:`WorldState`.

``Simulation(scenario)`` builds the road (:mod:`.road`), the ego (id 0), the
placed vehicles (ids 1..P in file order) and the random traffic (ids P+1..N in
placement order) — deterministically for ``scenario.seed`` — and, on a street (``road.street``),
the parked cars near the ego (:mod:`.parking`: static, not highway-env's, ids from 100,000). With
``traffic.fleet: mixed`` each random vehicle's body type and footprint come from :func:`harness.world.fleet.draw_body` (its own generator: the
seed and its id, so the placement's stream is the same draws), and a placed vehicle with a ``body`` but no
size gets the type's typical one; highway-env's ``LENGTH``/``WIDTH`` are set to the footprint. With ``traffic.warmup_s``
the world first runs that long (frames ``-W .. -1``, not shown), so frame 0 is the traffic
after the placement's braking wave; road features are placed from the camera at frame 0. Each
:meth:`Simulation.step` runs ``road.act(); road.step(dt)`` exactly once with
``dt = 1 / fps``; frame ``k`` has ``t = k / fps`` (frame count, no float
accumulation). highway-env's collision checks stay on (``crashed`` flags).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from harness.world import scenario as sc
from harness.world.scenario import ScenarioError
from harness.simulation.events import timed_events
from harness.simulation.parking import ParkedCars
from harness.simulation.placement import (ROAD_START_MARGIN_M, Footprint, cut_in_distance, fleet_sizes,
                                          placed_centre_x, placed_size, traffic_slots)
from harness.world.road import EGO_START_X_M, road_plan, road_profile
from harness.simulation.road import build_road, lane_centre_y
from harness.simulation.vehicles import Clock, ScenarioVehicle, StationaryVehicle
from harness.world.state import VehicleState, WorldState

LOOKAHEAD_M = 200.0
"""Road the ego must still have ahead of it at the scenario's end (m)."""


class Simulation:
    """A scenario's world, advanced one frame (``dt = 1 / fps``) per :meth:`step`."""

    def __init__(self, scenario: sc.Scenario) -> None:
        self.scenario = scenario
        self.fps = float(scenario.fps)
        self.dt = 1.0 / self.fps
        self._clock = Clock(self.fps)
        road_seed, traffic_seed = np.random.SeedSequence(scenario.seed).spawn(2)
        self.road = build_road(scenario.road, np.random.default_rng(road_seed))
        _check_events(scenario)
        _check_road_length(scenario)
        self.ego = self._make_ego()
        placed, footprints = self._make_placed()
        traffic = self._make_traffic(np.random.default_rng(traffic_seed), footprints)
        events = timed_events(list(scenario.events), self.ego)
        for v in [self.ego, *placed]:
            key = "ego" if v is self.ego else v.name
            if isinstance(v, ScenarioVehicle):
                v.events = events.get(key, [])
                for ev in v.events:
                    ev.prepare(v)
        self.road.vehicles = [self.ego, *(v for v in placed if isinstance(v, ScenarioVehicle)), *traffic]
        self.road.objects = [v for v in placed if isinstance(v, StationaryVehicle)]
        self._others = sorted([*placed, *traffic], key=lambda v: v.vid)
        self._warm_up(int(round(scenario.traffic.warmup_s * self.fps)))
        ego_x = float(self.ego.position[0])
        self.profile = road_profile(scenario.road.profile, scenario.camera.forward_offset_m, ego_x)
        self.plan = road_plan(scenario.road.curves, scenario.camera.forward_offset_m, ego_x)
        self.parked = ParkedCars(scenario.road, scenario.seed)

    # ---------------------------------------------------------------- public
    @property
    def frame(self) -> int:
        return self._clock.frame

    def state(self) -> WorldState:
        """The current frame's exact state (frame 0 = initial placement at t = 0)."""
        ego = vehicle_state(self.ego)
        return WorldState(frame=self._clock.frame, t=self._clock.t, ego=ego,
                          vehicles=(*(vehicle_state(v) for v in self._others), *self.parked.near(ego.x)),
                          profile=self.profile, plan=self.plan)

    def step(self) -> WorldState:
        """Advance exactly one frame (``road.act(); road.step(dt)``) and return the new state."""
        self.road.act()
        self.road.step(self.dt)
        self._clock.frame += 1
        return self.state()

    # ---------------------------------------------------------------- building
    def _warm_up(self, n_frames: int) -> None:
        """Run the world ``n_frames`` frames before frame 0 (clock at ``-n_frames .. -1``)."""
        self._clock.frame = -n_frames
        for _ in range(n_frames):
            self.road.act()
            self.road.step(self.dt)
            self._clock.frame += 1

    def _vehicle_kwargs(self) -> dict:
        t = self.scenario.traffic
        return dict(road=self.road, clock=self._clock, idm=t.idm, mobil=t.mobil)

    def _make_ego(self) -> ScenarioVehicle:
        s = self.scenario
        pos = np.array([EGO_START_X_M, lane_centre_y(s.ego.lane, s.road.lane_width_m)])
        return ScenarioVehicle(position=pos, speed=s.ego.speed_mps, vid=0, name=None,
                               behaviour=s.ego.behaviour, lane_changes=s.ego.lane_changes,
                               **self._vehicle_kwargs())

    def _make_placed(self) -> tuple[list[ScenarioVehicle | StationaryVehicle], list[Footprint]]:
        """The placed vehicles (ids 1..P) and the footprints at t = 0 of the ego and them."""
        s = self.scenario
        cut_ins = {e.vehicle: e for e in s.events if isinstance(e, sc.CutInEvent)}
        footprints = [Footprint(self.ego.position[0], self.ego.position[1], self.ego.LENGTH, self.ego.WIDTH)]
        names = ["the ego"]
        out: list[ScenarioVehicle | StationaryVehicle] = []
        for i, p in enumerate(s.vehicles, start=1):
            distance = p.distance_m
            if p.name in cut_ins:
                e = cut_ins[p.name]
                distance = cut_in_distance(e.gap_m, e.at_s, p.speed_mps, s.ego.speed_mps)
            length, width = placed_size(p.length_m, p.width_m, p.body, s.seed, i)
            x = placed_centre_x(EGO_START_X_M, s.camera.forward_offset_m, distance, length)
            y = lane_centre_y(s.ego.lane + p.lane, s.road.lane_width_m) + p.lateral_offset_m
            where = f"scenario {s.name!r}: vehicles.{i - 1} ({p.name!r})"
            if x - length / 2 < ROAD_START_MARGIN_M:
                raise ScenarioError(f"{where}: starts {x - length / 2:.1f} m from the road start; "
                                    f"it must start within {EGO_START_X_M - ROAD_START_MARGIN_M:.0f} m behind the ego")
            if x + length / 2 > s.road.length_m:
                raise ScenarioError(f"{where}: starts beyond the end of the {s.road.length_m:g} m road")
            fp = Footprint(x, y, length, width)
            for other, name in zip(footprints, names):
                if fp.overlaps(other):
                    raise ScenarioError(f"{where}: overlaps {name} at t = 0 (camera-to-rear distance {distance:.2f} m)")
            footprints.append(fp)
            names.append(repr(p.name))
            pos = np.array([x, y])
            if p.behaviour == "stationary":
                out.append(StationaryVehicle(self.road, pos, vid=i, name=p.name,
                                             length=length, width=width, body=p.body))
            else:
                out.append(ScenarioVehicle(position=pos, speed=p.speed_mps, vid=i, name=p.name,
                                           behaviour=p.behaviour, lane_changes=p.lane_changes,
                                           length=length, width=width, body=p.body, **self._vehicle_kwargs()))
                out[-1].lateral_offset_m = p.lateral_offset_m
        return out, footprints

    def _make_traffic(self, rng: np.random.Generator, occupied: list[Footprint]) -> list[ScenarioVehicle]:
        s, t = self.scenario, self.scenario.traffic
        first = len(s.vehicles) + 1
        # a mixed fleet: each vehicle's body and footprint from its own generator (the slots' stream untouched)
        fleet = fleet_sizes(s.seed, first, t.vehicles_count) if t.fleet == "mixed" else None
        try:
            slots = traffic_slots(rng, t.vehicles_count, s.road.lanes, s.road.lane_width_m, t.density,
                                  t.speed_range_mps, occupied, EGO_START_X_M, s.road.length_m,
                                  sizes=None if fleet is None else [(le, w) for _, le, w in fleet])
        except ValueError as e:
            raise ScenarioError(f"scenario {s.name!r}: traffic.vehicles_count: {e}") from None
        shapes = ([{} for _ in slots] if fleet is None
                  else [{"body": body, "length": le, "width": w} for body, le, w in fleet])
        return [ScenarioVehicle(position=np.array([slot.x, lane_centre_y(slot.lane, s.road.lane_width_m)]),
                                speed=slot.speed, vid=first + k, name=None, behaviour="idm",
                                lane_changes=t.lane_changes, **shape, **self._vehicle_kwargs())
                for k, (slot, shape) in enumerate(zip(slots, shapes))]


def simulate(scenario: sc.Scenario, n_frames: int | None = None) -> Iterator[WorldState]:
    """Frames ``0 .. n-1`` of the scenario (``n`` defaults to ``scenario.n_frames``); frame k has t = k / fps.

    With ``scenario.end_on_contact_s`` set, the frames stop that long after the first frame
    in which the ego's crash flag is set (a collision test ends at contact).
    """
    n = scenario.n_frames if n_frames is None else int(n_frames)
    if n <= 0:
        return
    sim = Simulation(scenario)
    state = sim.state()
    yield state
    contact_frame = None
    for _ in range(n - 1):
        if contact_frame is None and scenario.end_on_contact_s is not None and state.ego.crashed:
            contact_frame = state.frame
        if contact_frame is not None and (state.frame - contact_frame) / sim.fps >= scenario.end_on_contact_s - 1e-9:
            return
        state = sim.step()
        yield state


def vehicle_state(v: ScenarioVehicle | StationaryVehicle) -> VehicleState:
    """Exact state of one highway-env vehicle: centre, heading, speed, velocity, lane, size, crash flag."""
    vx, vy = v.velocity
    return VehicleState(
        id=v.vid, x=float(v.position[0]), y=float(v.position[1]), heading=float(v.heading),
        speed=float(v.speed), vx=float(vx), vy=float(vy), lane=int(v.lane_index[2]),
        length=float(v.LENGTH), width=float(v.WIDTH), crashed=bool(v.crashed), name=v.name,
        body=getattr(v, "body", None))



# -------------------------------------------------------------------- checks
def _check_events(s: sc.Scenario) -> None:
    """Events the schema allows but the simulation cannot perform."""
    behaviour = {v.name: v.behaviour for v in s.vehicles}
    cut_ins: set[str] = set()
    for i, e in enumerate(s.events):
        if e.vehicle != "ego" and behaviour[e.vehicle] == "stationary":
            raise ScenarioError(f"scenario {s.name!r}: events.{i}: vehicle {e.vehicle!r} is stationary "
                                f"and cannot {e.type.replace('_', ' ')}")
        if isinstance(e, sc.CutInEvent):
            if e.vehicle in cut_ins:
                raise ScenarioError(f"scenario {s.name!r}: events.{i}: vehicle {e.vehicle!r} has more than one cut_in")
            cut_ins.add(e.vehicle)


def _check_road_length(s: sc.Scenario) -> None:
    """The ego must have road ahead for the whole scenario (lanes end at ``road.length_m``)."""
    v_max = max([s.ego.speed_mps] + [e.target_speed_mps for e in s.events
                                     if isinstance(e, sc.SpeedChangeEvent) and e.vehicle == "ego"])
    drive_s = s.traffic.warmup_s + s.duration_s
    need = EGO_START_X_M + v_max * drive_s + LOOKAHEAD_M
    if s.road.length_m < need:
        raise ScenarioError(
            f"scenario {s.name!r}: road.length_m: {s.road.length_m:g} m is too short; the ego starts at "
            f"{EGO_START_X_M:g} m and drives up to {v_max * drive_s:.0f} m in {drive_s:g} s, "
            f"needing at least {need:.0f} m")
