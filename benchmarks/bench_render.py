"""Frames/s of simulation + rendering (colour + id pass + ground truth) with 30 vehicles.

Usage: python benchmarks/bench_render.py [--frames N] [--look simple|realistic|both] [--street] [--scenario S.yaml]
With ``--street`` the road is an urban street (two 3.25 m lanes, parking strips with 10 parked cars per 100 m
a side, pavements, the realistic look's frontage; ``road.street``) and the 30 vehicles drive at 8-13 m/s.
With ``--scenario`` that scenario file is timed instead (its render block's look replaced by ``--look``, its
camera resized to each resolution), e.g. ``scenarios/highway_cruise.yaml``.
Uses harness.simulation when present, else synthetic constant-velocity traffic.
Prints one line per resolution: wall-clock frames/s and the process CPU time per
frame (all threads; a fairer figure when other jobs share the cores).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from harness.bench.script import run_script
from harness.world.ground_truth import frame_truth
from harness.render.renderer import Renderer
from harness.world.scenario import Scenario, parse_scenario
from harness.world.state import VehicleState, WorldState


def scenario_for(width: int, height: int, look: str = "simple", street: bool = False) -> Scenario:
    road = {"lanes": 2, "lane_width_m": 3.25, "shoulder_width_m": 2.3, "street": {"parked_per_100m": 10}} \
        if street else {"lanes": 4}
    return parse_scenario({
        "name": "bench", "seed": 1, "fps": 15,
        "road": road,
        "traffic": {"vehicles_count": 30, "density": 1.5} | ({"speed_range_mps": [8, 13]} if street else {}),
        "ego": {"lane": 1, "speed_mps": 10.0 if street else 25.0},
        "camera": {"width": width, "height": height},
        "render": {"look": look},
    })


def synthetic_states(scenario: Scenario, n_frames: int, n_vehicles: int = 30):
    """Constant-velocity traffic around the ego (used when harness.simulation is absent)."""
    rng = np.random.default_rng(scenario.seed)
    lw, lanes, dt = scenario.road.lane_width_m, scenario.road.lanes, 1.0 / scenario.fps
    ego_lane = scenario.ego.lane
    lane = rng.integers(0, lanes, n_vehicles)
    x0 = 200.0 + np.sort(rng.uniform(-40, 220, n_vehicles))
    speed = rng.uniform(20, 30, n_vehicles)
    for k in range(n_frames):
        t = k * dt
        ego = VehicleState(0, 200.0 + 25.0 * t, ego_lane * lw, 0.0, 25.0, 25.0, 0.0, ego_lane, 5.0, 2.0)
        vs = tuple(VehicleState(i + 1, float(x0[i] + speed[i] * t), float(lane[i] * lw), 0.0, float(speed[i]),
                                float(speed[i]), 0.0, int(lane[i]), 5.0, 2.0) for i in range(n_vehicles)
                   if abs(x0[i] - 200.0) > 6 or lane[i] != ego_lane)
        yield WorldState(k, t, ego, vs)


def states(scenario: Scenario, n_frames: int):
    try:
        from harness.simulation.simulator import simulate
    except ImportError:
        return synthetic_states(scenario, n_frames), "synthetic"
    return simulate(scenario, n_frames), "harness.simulation"


def from_file(path: str, width: int, height: int, look: str) -> Scenario:
    """The scenario file with its look replaced and its camera at ``width`` x ``height``."""
    from harness.world.scenario import load_scenario_dict

    d = load_scenario_dict(path)                # a missing or malformed file: one line (ScenarioError)
    d["camera"] = {**(d.get("camera") or {}), "width": width, "height": height}
    d["render"] = {**(d.get("render") or {}), "look": look}
    return parse_scenario(d)


def bench(width: int, height: int, n_frames: int, look: str = "simple", street: bool = False,
          scenario_file: str | None = None) -> None:
    scenario = scenario_for(width, height, look, street) if scenario_file is None else \
        from_file(scenario_file, width, height, look)
    with Renderer(scenario) as renderer:
        it, source = states(scenario, n_frames + 3)
        t_sim = t_render = t_truth = 0.0
        n_obj = 0
        t0, c0 = time.perf_counter(), time.process_time()
        for k in range(n_frames + 3):
            a = time.perf_counter()
            world = next(it)
            b = time.perf_counter()
            frame = renderer.render(world)
            c = time.perf_counter()
            truth = frame_truth(world, renderer.camera, frame)
            d = time.perf_counter()
            if k == 2:  # warm-up done
                t0, c0 = d, time.process_time()
                t_sim = t_render = t_truth = 0.0
                n_obj = 0
                continue
            t_sim, t_render, t_truth = t_sim + b - a, t_render + c - b, t_truth + d - c
            n_obj += len(truth.objects)
        total, cpu = time.perf_counter() - t0, time.process_time() - c0
    where = f", {scenario.name}" if scenario_file else ", street" if street else ""
    print(f"{look} look{where}, {width}x{height} ({source}, {len(world.vehicles)} vehicles, {n_obj / n_frames:.1f} visible): "
          f"{n_frames / total:.1f} frames/s (process CPU {1e3 * cpu / n_frames:.1f} ms/frame, all threads); per frame sim {1e3 * t_sim / n_frames:.1f} ms, "
          f"render {1e3 * t_render / n_frames:.1f} ms, truth {1e3 * t_truth / n_frames:.1f} ms")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--look", choices=("simple", "realistic", "both"), default="both")
    ap.add_argument("--street", action="store_true", help="an urban street with parked cars (road.street)")
    ap.add_argument("--scenario", default=None, metavar="S.yaml", help="time this scenario file instead")
    args = ap.parse_args()
    for look in ("simple", "realistic") if args.look == "both" else (args.look,):
        for w, h in ((640, 360), (1280, 720)):
            bench(w, h, args.frames, look, args.street, args.scenario)


if __name__ == "__main__":
    run_script(main)
