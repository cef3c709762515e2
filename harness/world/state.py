"""Exact simulation state of one frame, as the simulation adapter exposes it.

Road frame (highway-env's): ``x`` along the road (m), ``y`` across it (m,
increasing towards higher lane indices, i.e. to the right of travel), heading
in rad from +x towards +y. Lane 0 is the leftmost lane; its centre is y = 0.
With a vertical ``profile`` (:mod:`harness.world.road_profile`) the point ``(x, y)`` lies at height
``profile.z(x)``; without one the road is the plane z = 0. With a horizontal ``plan``
(:mod:`harness.world.road_plan`) the point lies at the horizontal position ``plan.to_plane(x, y)``: ``x`` is
then the arc length along the bent lane 0 centre; without one the road is straight.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from harness.world.road_plan import RoadPlan
from harness.world.road_profile import RoadProfile


@dataclass(frozen=True)
class VehicleState:
    id: int                 # stable across frames; the ego is id 0
    x: float                # centre, road frame, m
    y: float
    heading: float          # rad
    speed: float            # m/s along heading
    vx: float               # road-frame velocity, m/s
    vy: float
    lane: int               # absolute lane index
    length: float           # m
    width: float            # m
    crashed: bool = False
    name: str | None = None  # scenario name for placed vehicles
    body: str | None = None  # body type (harness.world.vehicles.BODY_TYPES); None: the footprint decides


@dataclass(frozen=True)
class WorldState:
    frame: int
    t: float                # = frame / fps, s
    ego: VehicleState
    vehicles: tuple[VehicleState, ...] = field(default_factory=tuple)  # every non-ego vehicle
    profile: RoadProfile | None = None   # the road's vertical profile; None: level
    plan: RoadPlan | None = None         # the road's horizontal curves; None: straight
