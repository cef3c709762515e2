"""Benchmark the Monte Carlo IDM/MOBIL risk estimator: ms per frame (assess call), numba and numpy backends.

Prints, per backend, for 500 and 1000 rollouts with 5 and 10 vehicles on a 3-lane
scene, the median wall-clock and process-CPU time per ``assess`` over repeated
calls (the first call, which draws and caches the drivers, is reported apart; the
numba kernel is compiled / loaded from its cache before, and that one-off time is
printed). Process-CPU time is the figure to compare on a shared machine (wall time
grows with the load, which is printed before and after). Target (issue 5): <= 10 ms
per frame with 500 rollouts.
Usage: python benchmarks/bench_risk_mc.py [--repeats 20] [--dt 0.2] [--backends numba numpy]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from harness.bench.script import run_script
from monorarp.risk.monte_carlo.estimator import MonteCarloRisk
from monorarp.risk.monte_carlo import rollout_numba
from monorarp.core.types import ObjectState


def scene(n_vehicles: int, seed: int = 1) -> dict[int, ObjectState]:
    rng = np.random.default_rng(seed)
    return {i: ObjectState(i, float(rng.choice([-3.7, 0.0, 3.7]) + rng.normal(0, 0.3)),
                           float(rng.uniform(8, 100)), float(rng.normal(0, 0.2)), float(rng.normal(0, 3)))
            for i in range(1, n_vehicles + 1)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=20)
    ap.add_argument("--dt", type=float, default=0.2)
    ap.add_argument("--backends", nargs="+", default=["numba", "numpy"], choices=["numba", "numpy"])
    args = ap.parse_args()
    print(f"dt={args.dt} s, horizon 10 s, lanes -1..1, ego 25 m/s; load average {os.getloadavg()}")
    if "numba" in args.backends:
        if not rollout_numba.NUMBA_AVAILABLE:
            print(f"numba unavailable ({rollout_numba.NUMBA_IMPORT_ERROR}): skipping it")
            args.backends = [b for b in args.backends if b != "numba"]
        else:
            t0 = time.perf_counter()
            rollout_numba.warm_up()
            print(f"numba kernel compile / cache load (first call in this process): "
                  f"{(time.perf_counter() - t0) * 1e3:.0f} ms")
    print(f"{'backend':>7} {'rollouts':>8} {'vehicles':>8} {'first ms':>9} {'wall ms':>8} {'cpu ms':>7} {'risk':>6}")
    for backend in args.backends:
        for n_roll in (500, 1000):
            for n_veh in (5, 10):
                est = MonteCarloRisk(n_rollouts=n_roll, dt=args.dt, backend=backend)
                st = scene(n_veh)
                t0 = time.perf_counter()
                est.assess(st, 0.0, ego_speed=25.0)
                first = (time.perf_counter() - t0) * 1e3
                wall, cpu = [], []
                for k in range(args.repeats):
                    w0, c0 = time.perf_counter(), time.process_time()
                    r = est.assess(st, 0.1 * k, ego_speed=25.0)
                    wall.append(time.perf_counter() - w0)
                    cpu.append(time.process_time() - c0)
                print(f"{backend:>7} {n_roll:>8} {n_veh:>8} {first:>9.1f} {np.median(wall) * 1e3:>8.1f} "
                      f"{np.median(cpu) * 1e3:>7.1f} {r.risk:>6.3f}")
    print(f"load average after: {os.getloadavg()}")


if __name__ == "__main__":
    run_script(main)
