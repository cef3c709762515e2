"""Replay the state estimator and the warning stage over cached tracks of a protocol's runs.

How the warning stage's defaults were chosen (``monorarp/warning/fcw.py``, ``monorarp/state/estimator.py``):
the detector and the tracker run once per run of a protocol (by default the tuning set,
``scenarios/fcw/tuning.yaml``, which shares no speed, gap or seed with a scorecard suite or
the CI subset) and their tracks are cached, with the default state estimator's patch
registrations (scales, patch centres and shifts per frame and track, which need the frames); then each parameter set of the grid replays only
the state estimator and the warning stage (a fraction of a second per run, in ``--workers``
processes) and is scored with the scorecard's own rules: trials passed and false-alarm episodes
in the nominal runs.

    python scripts/tune_warning.py [--protocol scenarios/fcw/tuning.yaml] [--cache DIR]
        [--workers N] [--trials N] [--grid '{"state": {"pixel_std": [0.5, 1.0]}, "warning": {"lateral_sigmas": [2, 3]}}']

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

import numpy as np

from harness.run.frame_feed import rendered_frames
from harness.world.scenario import parse_scenario
from harness.scorecard.run import ScorecardOptions, build_tasks
from harness.scorecard.score import trial_passed
from harness.scoring.warnings import warning_metrics
from monorarp.pipeline import registry
from monorarp.pipeline.config import PipelineConfig
from monorarp.pipeline.runner import Pipeline, tracker_input
from monorarp.core.types import FrameResult, RiskEstimate

_NO_IMAGE = np.zeros((1, 1), dtype=np.uint8)   # the recorded registration needs no frame


def tracks_key(task) -> str:
    """What the cached tracks depend on: the scenario, the frames, the detector and the tracker."""
    made_by = {k: task.pipeline.get(k) for k in ("detector", "tracker")}
    return hashlib.sha256(json.dumps([task.scenario, made_by, task.frames], sort_keys=True).encode()).hexdigest()


#: what a cache's ``registration`` holds: 2 = (scale, scale_std, centre_x, shift_x) per frame and track
REGISTRATION_VERSION = 2


class RecordingRegistration:
    """Wraps a state estimator's patch registration and records its results per frame: ``record[frame
    index][track id] = (scale, scale_std, centre_x, shift_x)`` (set ``frame`` before each update), and the
    frame's reduction factor (``k``)."""

    def __init__(self, inner) -> None:
        self.inner, self.frame, self.record, self.k = inner, None, {}, 1
        self.pixel_std = inner.pixel_std

    def reset(self) -> None:
        self.inner.reset()

    def reduction(self, width: int) -> int:
        return self.inner.reduction(width)

    def update(self, image, ids, boxes, valid):
        out = self.inner.update(image, ids, boxes, valid)
        self.k = self.inner.reduction(image.shape[1])
        self.record[self.frame] = {int(i): tuple(float(v) for v in vals) for i, *vals in zip(ids, *out)
                                   if np.isfinite(vals[0])}
        return out


class RecordedRegistration:
    """Stands in for the registration in a replay: the recorded results of frame ``frame`` (NaN for a
    track not recorded); needs no image. ``k``: the recorded frames' reduction factor."""

    def __init__(self, record: dict, pixel_std: float = 0.2, k: int = 1) -> None:
        self.record, self.frame, self.pixel_std, self.k = record, None, pixel_std, k
        self.reset()

    def reduction(self, width: int) -> int:
        return self.k

    def reset(self) -> None:
        self._valid: set[int] = set()

    def update(self, image, ids, boxes, valid):
        """As the registration: a track needs a valid box in this call and the previous one."""
        got, none = self.record.get(self.frame, {}), (np.nan,) * 4
        rows = np.array([got.get(int(i), none) if v and int(i) in self._valid else none
                         for i, v in zip(ids, valid)], dtype=float).reshape(-1, 4)
        self._valid = {int(i) for i, v in zip(ids, valid) if v}
        return rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3]


def cached_tracks(task, cache: Path, load: bool = True) -> dict | None:
    """{camera, frames: [(index, t, tracks)], truths, registration} of one run, computed once (``load`` False:
    only make sure the cache holds it). ``registration``: the default state estimator's patch scales
    (:class:`RecordingRegistration`); a cache from before it had none gets them from the frames rendered again."""
    key = tracks_key(task)
    path = cache / f"{task.id}-{key[:12]}.pkl"
    data = pickle.loads(path.read_bytes()) if path.is_file() else None
    if data is not None and data.get("registration_version") == REGISTRATION_VERSION:
        return data if load else None
    scenario = parse_scenario(task.scenario)
    camera = scenario.camera.model()
    pipe = None if data is not None else Pipeline.from_config(PipelineConfig.model_validate(task.pipeline), camera)
    state = registry.build("state", "geometric", {}, camera)
    state.registration = recorder = RecordingRegistration(state.registration)
    frames, truths = [], []
    for k, (frame, truth) in enumerate(rendered_frames(scenario, task.frames)):
        if pipe is not None:
            dets = tracker_input(pipe.tracker, pipe.detect(frame.image))
            frames.append((frame.index, frame.t, pipe.tracker.update(frame.image, dets, frame.t)))
            truths.append(truth)
        tracks = (data["frames"] if data is not None else frames)[k][2]
        recorder.frame = frame.index
        state.update(tracks, frame.t, image=frame.image)
    data = data if data is not None else {"camera": camera, "frames": frames, "truths": truths}
    data["registration"], data["registration_k"] = recorder.record, recorder.k
    data["registration_version"] = REGISTRATION_VERSION
    cache.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_bytes(pickle.dumps(data))
    tmp.replace(path)
    return data


def replay(data: dict, state_kw: dict, warning_kw: dict) -> dict:
    """``warning.*`` metrics of one run with these state-estimator and warning parameters."""
    state = registry.build("state", "geometric", dict(state_kw), data["camera"])
    recorded = None
    if state.registration is not None:
        state.registration = recorded = RecordedRegistration(data["registration"], state.registration.pixel_std,
                                                             data.get("registration_k", 1))
    warn = registry.build("warning", "fcw", dict(warning_kw), data["camera"])
    results = []
    for (index, t, tracks), truth in zip(data["frames"], data["truths"]):
        if recorded is not None:
            recorded.frame = index
        states = state.update(tracks, t, image=_NO_IMAGE)
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
    ap.add_argument("--workers", type=int, default=2, help="processes that compute missing tracks and replay")
    ap.add_argument("--trials", type=int, default=None, help="trials per test (default: the protocol's)")
    ap.add_argument("--why", action="store_true", help="also print each false alarm's one-line cause")
    ap.add_argument("--grid", default='{"state": {}, "warning": {}}', help="JSON: stage -> parameter -> values")
    args = ap.parse_args()
    trials, tasks = build_tasks(ScorecardOptions(protocol_files=[args.protocol], trials=args.trials, progress=False))
    with multiprocessing.get_context("spawn").Pool(args.workers) as pool:
        pool.starmap(cached_tracks, [(task, args.cache, False) for task in tasks], chunksize=1)
        for state_kw, warning_kw in grid_points(json.loads(args.grid)):
            metrics = pool.starmap(replay_cached, [(task, args.cache, state_kw, warning_kw) for task in tasks], chunksize=4)
            print(json.dumps({"state": state_kw, "warning": warning_kw}),
                  *score_grid_point(trials, metrics, args.why), sep="\n" if args.why else " ", flush=True)


def replay_cached(task, cache: Path, state_kw: dict, warning_kw: dict) -> dict:
    """:func:`replay` of one task's cached tracks (a worker loads them itself: nothing big crosses processes)."""
    return replay(cached_tracks(task, cache), state_kw, warning_kw)


def score_grid_point(trials, metrics: list[dict], why: bool) -> list[str]:
    """Trials passed, false alarms (per hour of the nominal runs) and first-warning TTCs of one parameter set."""
    passed, n_tests, fa, hours, ttcs, causes = 0, 0, 0, 0.0, [], []
    for trial, m in zip(trials, metrics):
        if trial.kind == "nominal":
            fa += sum(e["false_alarm"] for e in m["episode_list"])
            causes += [f"  {trial.key} seed {trial.trial}: {e['why']}" for e in m["episode_list"] if e["false_alarm"]]
            hours += m["exposure_s"] / 3600
            continue
        n_tests += 1
        passed += trial_passed(trial.kind, m, trial.required_ttc_s)
        ttcs.append(f"{trial.test}:{'-' if m['first_warning_ttc_s'] is None else round(m['first_warning_ttc_s'], 2)}")
    rate = f"{fa / hours:.1f}/h over {hours:.2f} h" if hours > 0 else "no nominal runs"
    return [f"trials passed {passed}/{n_tests}", f"false alarms {fa} ({rate})", " ".join(ttcs), *(causes if why else [])]


if __name__ == "__main__":
    main()
