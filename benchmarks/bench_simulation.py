"""Milliseconds per simulation step (``road.act(); road.step(dt)`` + WorldState) vs number of vehicles.

Compares the adapter's vectorised road (:class:`harness.simulation.road.StraightRoad`) with
highway-env's own ``Road`` on the same scenario (identical results, see tests/test_simulation.py).
Run: ``python benchmarks/bench_simulation.py``.
"""

from __future__ import annotations

import time

from highway_env.road.road import Road

from harness.bench.script import run_script
from harness.world.scenario import parse_scenario
from harness.simulation.simulator import Simulation

FRAMES = 300


def ms_per_frame(n_vehicles: int, plain: bool) -> float:
    sc = parse_scenario({"name": "bench", "seed": 0, "road": {"lanes": 4},
                         "ego": {"behaviour": "idm", "speed_mps": 22},
                         "traffic": {"vehicles_count": n_vehicles, "density": 1.5, "speed_range_mps": [18, 28]}})
    sim = Simulation(sc)
    if plain:
        sim.road.__class__ = Road
    t0 = time.perf_counter()
    for _ in range(FRAMES):
        sim.step()
    return (time.perf_counter() - t0) / FRAMES * 1e3


def main() -> None:
    print(f"{'vehicles':>8}  {'adapter ms/frame':>16}  {'highway-env Road ms/frame':>25}   ({FRAMES} frames, 15 fps)")
    for n in (10, 30, 60):
        print(f"{n + 1:>8}  {ms_per_frame(n, False):>16.2f}  {ms_per_frame(n, True):>25.2f}")


if __name__ == "__main__":
    run_script(main)
