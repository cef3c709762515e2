"""Vehicle geometry of the world: the body dimensions (m) of a vehicle of a given footprint.

One definition for everything that needs a vehicle's shape: the renderer builds its mesh from it, the
ground truth takes its 3-D box height from it, the exporters its KITTI type (Car or Truck).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

#: A vehicle longer than this (m) is built (and labelled) as a truck.
TRUCK_MIN_LENGTH_M = 7.0


@dataclass(frozen=True)
class VehicleLayout:
    """Dimensions (m) of one vehicle's mesh, in its model frame."""

    length: float
    width: float
    truck: bool
    clearance: float          # underside of the body above the ground
    wheel_radius: float
    wheel_width: float
    rear_axle_x: float        # X of the rear axle (negative)
    front_axle_x: float
    wheel_y: float            # |Y| of the wheels' outer faces
    belt: float               # top of the lower body
    roof: float               # total height

    @property
    def rear_overhang(self) -> float:
        return self.rear_axle_x + self.length / 2


@functools.lru_cache(maxsize=1024)
def vehicle_layout(length: float, width: float) -> VehicleLayout:
    """The mesh dimensions for a vehicle of ``length`` x ``width`` metres."""
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


def vehicle_height(length: float, width: float) -> float:
    """Roof height (m) of the mesh for this footprint: the 3-D box's height."""
    return vehicle_layout(length, width).roof
