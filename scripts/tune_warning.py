"""Replay the state estimator and the warning stage over cached tracks of a protocol's runs.

How the warning stage's defaults were chosen (``monorarp/warning.py``, ``monorarp/state.py``):
the detector and the tracker run once per run of a protocol (by default the tuning set,
``scenarios/fcw/tuning.yaml``, which shares no speed, gap or seed with a scorecard suite or
the CI subset) and their tracks are cached; then each parameter set of the grid replays only
the state estimator and the warning stage (milliseconds per run) and is scored with the
scorecard's own rules: trials passed and false-alarm episodes in the nominal runs.

    python scripts/tune_warning.py [--protocol scenarios/fcw/tuning.yaml] [--cache DIR]
        [--workers N] [--grid '{"state": {"pixel_std": [0.5, 1.0]}, "warning": {"lateral_sigmas": [2, 3]}}']

Prints one line per parameter set. Needs the harness (renders the runs on first use).
"""

from __future__ import annotations

import argparse
import hashlib
import itertools
import json
import multiprocessing
import pickle
from pathlib import Path

from harness.frame_feed import rendered_frames
from harness.scenario import parse_scenario
from harness.scorecard.run import ScorecardOptions, build_tasks
from harness.scorecard.score import trial_passed
from harness.scoring.warnings import warning_metrics
from monorarp import registry
from monorarp.pipeline import Pipeline, PipelineConfig
from monorarp.types import FrameResult, RiskEstimate


def tracks_key(task) -> str:
    """What the cached tracks depend on: the scenario, the frames, the detector and the tracker."""
    made_by = {k: task.pipeline.get(k) for k in ("detector", "tracker")}
    return hashlib.sha256(json.dumps([task.scenario, made_by, task.frames], sort_keys=True).encode()).hexdigest()


def cached_tracks(task, cache: Path) -> dict:
    """{camera, frames: [(index, t, tracks)], truths} of one run, computed once."""
    key = tracks_key(task)
    path = cache / f"{task.id}-{key[:12]}.pkl"
    if path.is_file():
        return pickle.loads(path.read_bytes())
    scenario = parse_scenario(task.scenario)
    camera = scenario.camera.model()
    cfg = PipelineConfig.model_validate(task.pipeline)
    pipe = Pipeline.from_config(cfg, camera)
    frames, truths = [], []
    for frame, truth in rendered_frames(scenario, task.frames):
        dets = pipe.detector.detect(frame.image)
        frames.append((frame.index, frame.t, pipe.tracker.update(frame.image, dets, frame.t)))
        truths.append(truth)
    data = {"camera": camera, "frames": frames, "truths": truths}
    cache.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_bytes(pickle.dumps(data))
    tmp.replace(path)
    return data


def replay(data: dict, state_kw: dict, warning_kw: dict) -> dict:
    """``warning.*`` metrics of one run with these state-estimator and warning parameters."""
    state = registry.build("state", "geometric", dict(state_kw), data["camera"])
    warn = registry.build("warning", "fcw", dict(warning_kw), data["camera"])
    results = []
    for (index, t, tracks), truth in zip(data["frames"], data["truths"]):
        states = state.update(tracks, t)
        w = warn.update(states, None, t, ego_speed=truth.ego.speed)   # the true speed: the tracks hold no frames
        results.append(FrameResult(index=index, t=t, detections=[], tracks=tracks, states=states,
                                   risk=RiskEstimate(risk=0.0), warning=w))
    return warning_metrics(data["truths"], results, warn.ttc_threshold_s)


def grid_points(grid: dict) -> list[tuple[dict, dict]]:
    axes = [(stage, k, v) for stage in ("state", "warning") for k, v in grid.get(stage, {}).items()]
    out = []
    for combo in itertools.product(*[v for _, _, v in axes]):
        kw = {"state": {}, "warning": {}}
        for (stage, k, _), value in zip(axes, combo):
            kw[stage][k] = value
        out.append((kw["state"], kw["warning"]))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--protocol", type=Path, default=Path("scenarios/fcw/tuning.yaml"))
    ap.add_argument("--cache", type=Path, default=Path(".cache/tune_warning"))
    ap.add_argument("--workers", type=int, default=2, help="processes that compute missing tracks")
    ap.add_argument("--why", action="store_true", help="also print each false alarm's one-line cause")
    ap.add_argument("--grid", default='{"state": {}, "warning": {}}', help="JSON: stage -> parameter -> values")
    args = ap.parse_args()
    trials, tasks = build_tasks(ScorecardOptions(protocol_files=[args.protocol], progress=False))
    with multiprocessing.get_context("spawn").Pool(args.workers) as pool:
        cached = pool.starmap(cached_tracks, [(task, args.cache) for task in tasks], chunksize=1)
    runs = list(zip(trials, cached))
    for state_kw, warning_kw in grid_points(json.loads(args.grid)):
        passed, n_tests, fa, hours, ttcs, why = 0, 0, 0, 0.0, [], []
        for trial, data in runs:
            m = replay(data, state_kw, warning_kw)
            if trial.kind == "nominal":
                fa += sum(e["false_alarm"] for e in m["episode_list"])
                if args.why:
                    why += [f"  {trial.key} seed {trial.trial}: {e['why']}" for e in m["episode_list"] if e["false_alarm"]]
                hours += m["exposure_s"] / 3600
                continue
            n_tests += 1
            passed += trial_passed(trial.kind, m, trial.required_ttc_s)
            ttcs.append(f"{trial.test}:{'-' if m['first_warning_ttc_s'] is None else round(m['first_warning_ttc_s'], 2)}")
        print(json.dumps({"state": state_kw, "warning": warning_kw}), f"trials passed {passed}/{n_tests}",
              f"false alarms {fa} ({fa / hours:.0f}/h)", " ".join(ttcs), *why, sep="\n" if why else " ", flush=True)


if __name__ == "__main__":
    main()
