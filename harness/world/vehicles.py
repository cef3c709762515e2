"""Vehicle geometry of the world: the body dimensions (m) of a vehicle of a given footprint and body type.

One definition for everything that needs a vehicle's shape: the renderer builds its mesh from it, the
ground truth takes its 3-D box height from it, the exporters its KITTI type (:func:`kitti_type`).

``body`` is one of :data:`BODY_TYPES` (a fleet's vehicle, :mod:`harness.world.fleet`) or None: then
the footprint alone decides, as it always has (longer than :data:`TRUCK_MIN_LENGTH_M`: a truck with a
3.6 m box body; else a 1.45 m car, or a 2.1 m van over 5.5 m). Every layout is a pure function of
``(length, width, body)``: a body type's height, clearance, wheels, overhangs and cab/box split follow
from its footprint (real vehicles of that type: the table in :mod:`harness.world.fleet`).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

#: A vehicle longer than this (m) is built (and labelled) as a truck when it has no body type.
TRUCK_MIN_LENGTH_M = 7.0

#: The body types of a fleet: five cars, a van, a pickup, two heavy goods vehicles and a bus.
BODY_TYPES = ("hatchback", "saloon", "estate", "suv", "van", "pickup", "box_truck", "artic", "bus")
HEAVY_BODIES = ("box_truck", "artic", "bus")

#: KITTI's class of each body type (KITTI's object devkit: Car, Van, Truck, ...; its labellers put SUVs and
#: pickups under Car, vans and minibuses under Van, and buses under Truck: e.g. the 12.34 m x 2.85 m bus of
#: training label 000001). Without a body type: Truck for the footprint's trucks, else Car.
KITTI_TYPE = {"hatchback": "Car", "saloon": "Car", "estate": "Car", "suv": "Car", "pickup": "Car", "van": "Van",
              "box_truck": "Truck", "artic": "Truck", "bus": "Truck"}


@dataclass(frozen=True)
class VehicleLayout:
    """Dimensions (m) of one vehicle's mesh, in its model frame (X forward, origin at the footprint centre)."""

    length: float
    width: float
    truck: bool               # a heavy vehicle's box-bodied build (trucks, artics, buses)
    clearance: float          # underside of the body above the ground
    wheel_radius: float
    wheel_width: float
    rear_axle_x: float        # X of the rear-most axle (negative)
    front_axle_x: float
    wheel_y: float            # |Y| of the wheels' outer faces
    belt: float               # top of the lower body (a pickup: its bed rails; a bus: its window line)
    roof: float               # total height
    body: str | None = None   # the body type; None: the footprint's rule
    cab_length: float = 0.0   # trucks and artics: the cab; a pickup: the cab and bonnet ahead of the bed
    rear_axles: tuple[float, ...] = ()   # X of every axle behind the front one (rear-most first); () = default

    @property
    def rear_overhang(self) -> float:
        return self.rear_axle_x + self.length / 2

    @property
    def axles(self) -> tuple[float, ...]:
        """X of every axle, rear-most first, the front axle last."""
        rear = self.rear_axles or ((self.rear_axle_x, self.rear_axle_x + 1.3) if self.truck else (self.rear_axle_x,))
        return (*rear, self.front_axle_x)


def _ramp(length: float, xs, ys) -> float:
    """``ys`` at ``length`` linearly between the breakpoints ``xs`` (held beyond them), rounded to the mm."""
    return round(float(np.interp(length, xs, ys)), 3)


@functools.lru_cache(maxsize=1024)
def vehicle_layout(length: float, width: float, body: str | None = None) -> VehicleLayout:
    """The mesh dimensions for a vehicle of ``length`` x ``width`` metres and body type ``body``."""
    if body is not None:
        return _body_layout(float(length), float(width), body)
    if length > TRUCK_MIN_LENGTH_M:
        r = 0.5
        rear_oh = min(0.25 * length, 2.5)
        return VehicleLayout(length, width, True, 0.45, r, 0.3, -length / 2 + rear_oh,
                             length / 2 - 1.4, width / 2 - 0.05, 1.1, 3.6)
    r = 0.32
    rear_oh = float(np.clip(0.19 * length, 0.8, 1.1))
    front_oh = float(np.clip(0.18 * length, 0.7, 1.0))
    roof = 1.45 if length <= 5.5 else 2.1
    return VehicleLayout(length, width, False, 0.17, r, 0.22, -length / 2 + rear_oh,
                         length / 2 - front_oh, width / 2 - 0.04, 0.95, roof)


#: Per light body type: clearance, wheel radius, wheel width, rear overhang (fraction of the length, clipped
#: to [lo, hi]), front overhang (likewise), belt height, roof height ramp (lengths, heights). Typical of the
#: type's best-sellers (e.g. hatchback: Polo, Golf, Clio, Corsa; saloon: 3 Series, A4, Passat, Camry; estate:
#: Octavia Combi, Passat Variant; SUV: T-Roc, Qashqai, Tiguan, RAV4, X5; pickup: Hilux, Ranger, F-150; van:
#: Berlingo, Transit Custom, Sprinter).
_LIGHT = {
    "hatchback": (0.15, 0.31, 0.21, (0.17, 0.65, 0.85), (0.20, 0.70, 0.90), 0.93, ((3.6, 4.4), (1.45, 1.49))),
    "saloon": (0.15, 0.32, 0.22, (0.22, 0.95, 1.15), (0.20, 0.85, 1.00), 0.95, ((4.4, 5.0), (1.43, 1.47))),
    "estate": (0.16, 0.32, 0.22, (0.21, 0.95, 1.10), (0.19, 0.85, 1.00), 0.96, ((4.5, 5.0), (1.46, 1.50))),
    "suv": (0.21, 0.36, 0.23, (0.20, 0.80, 1.05), (0.19, 0.80, 1.00), 1.05, ((4.1, 4.9), (1.58, 1.76))),
    "pickup": (0.23, 0.39, 0.26, (0.24, 1.20, 1.45), (0.17, 0.85, 1.00), 1.16, ((5.2, 5.9), (1.80, 1.96))),
    "van": (0.18, 0.34, 0.23, (0.18, 0.80, 1.25), (0.17, 0.75, 1.00), 1.05,
            ((4.4, 5.0, 5.9, 6.9), (1.82, 1.98, 2.45, 2.72))),
}


def _body_layout(length: float, width: float, body: str) -> VehicleLayout:
    if body not in BODY_TYPES:
        raise ValueError(f"body {body!r} is not one of {', '.join(BODY_TYPES)}")
    hl = length / 2
    if body in _LIGHT:
        cl, r, ww, (fr, rlo, rhi), (ff, flo, fhi), belt, (xs, hs) = _LIGHT[body]
        rear_oh = round(float(np.clip(fr * length, rlo, rhi)), 3)
        front_oh = round(float(np.clip(ff * length, flo, fhi)), 3)
        cab = round(float(np.clip(0.71 * length, 3.4, 4.2)), 3) if body == "pickup" else 0.0
        return VehicleLayout(length, width, False, cl, r, ww, -hl + rear_oh, hl - front_oh, width / 2 - 0.045,
                             belt, _ramp(length, xs, hs), body, cab)
    if body == "box_truck":   # rigid lorry: 7.5 t (single rear axle) to 26 t (tandem)
        rear_oh = round(min(0.22 * length, 2.5), 3)
        ra = -hl + rear_oh
        axles = (ra,) if length <= 9.0 else (ra, ra + 1.3)
        return VehicleLayout(length, width, True, 0.45, 0.5, 0.3, ra, hl - 1.4, width / 2 - 0.05, 1.1,
                             _ramp(length, (7.0, 10.5), (3.35, 3.8)), body, 2.3, axles)
    if body == "artic":       # tractor and semi-trailer as one rigid footprint: tri-axle trailer, 4x2 tractor
        ra = -hl + 2.2
        front = hl - 1.45
        axles = (ra, ra + 1.31, ra + 2.62, front - 3.7)
        return VehicleLayout(length, width, True, 0.45, 0.5, 0.3, ra, front, width / 2 - 0.05, 1.1,
                             _ramp(length, (15.5, 16.5), (3.95, 4.0)), body, 2.3, axles)
    # bus: a 2-axle city bus or coach, the window line at 1.15 m, long overhangs
    rear_oh = round(float(np.clip(0.26 * length, 2.7, 3.5)), 3)
    front_oh = round(float(np.clip(0.22 * length, 2.4, 2.8)), 3)
    return VehicleLayout(length, width, True, 0.30, 0.5, 0.3, -hl + rear_oh, hl - front_oh, width / 2 - 0.06,
                         1.15, _ramp(length, (10.5, 13.5), (3.05, 3.55)), body, 0.0, (-hl + rear_oh,))


def vehicle_height(length: float, width: float, body: str | None = None) -> float:
    """Roof height (m) of the mesh for this footprint and body type: the 3-D box's height."""
    return vehicle_layout(length, width, body).roof


def kitti_type(length: float, width: float, body: str | None = None) -> str:
    """KITTI class of a vehicle (:data:`KITTI_TYPE`; without a body type Truck for the footprint's trucks, else Car)."""
    if body is not None:
        return KITTI_TYPE[body]
    return "Truck" if vehicle_layout(float(length), float(width)).truck else "Car"
