"""``monorarp scorecard``: run the collision-warning protocols, score them, write ``scorecard.json``.

Layout of ``DIR`` (as a sweep's: each run directory appears complete or not at all,
``--resume`` skips runs already done with the same parameters)::

    DIR/runs/<suite>__<test>__<parameters>__t<trial>/   one run (harness.sweep.worker)
    DIR/scorecard.json                                  tests, false_alarms, risk, config
    DIR/summary.json, summary.csv                       per run, as a sweep's (for ``monorarp check``)
    DIR/report.html                                     the scorecard section (harness.scorecard.report)

Every protocol, option and pipeline is checked before anything is written: a
problem raises :class:`~monorarp.core.errors.UserError` (one line, exit 2).
"""

from __future__ import annotations

import csv
import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from harness.world.scenario import ScenarioError, parse_scenario
from harness.scorecard import score
from harness.scorecard.protocols import ProtocolError, Trial, expand_protocol, load_protocol
from harness.scoring.warnings import braking_alarm
from harness.sweep.executors import Executor, make_executor
from harness.sweep.expand import RunTask, inject_seeds, sanitize
from harness.sweep.orchestrate import execute, finished, prepare_out_dir
from harness.sweep.spec import Variant, run_mapping
from harness.sweep.worker import METRICS_JSON, RUN_JSON
from monorarp.core.readers import read_json_or_none
from monorarp.app.common_options import check_frames
from monorarp.app.options import CLI_EGO_SPEED
from monorarp.warning.thresholds import TTC_CUE_THRESHOLD_S
from monorarp.pipeline.config import PipelineConfig

PROTOCOL_DIR = Path(__file__).resolve().parents[2] / "scenarios" / "fcw"
SUITES = ("nhtsa", "ncap", "cut_in", "nominal", "risk")
SCORECARD_JSON = "scorecard.json"
REPORT_HTML = "report.html"


@dataclass
class ScorecardOptions:
    suites: Sequence[str] = SUITES
    protocol_dir: Path = PROTOCOL_DIR
    protocol_files: Sequence[Path] = ()          # explicit files instead of <protocol_dir>/<suite>.yaml
    detector: str = PipelineConfig().detector.name   # registered name, "oracle" or .onnx path (relative: to the cwd)
    detector_kwargs: dict = field(default_factory=dict)
    tracker: str = PipelineConfig().tracker.name
    warning_kwargs: dict = field(default_factory=dict)
    trials: int | None = None
    frames: int | None = None
    executor: str = "local"
    workers: int = 1
    address: str | None = None
    resume: bool = False
    progress: bool = True
    run_timeout_s: float | None = None           # a run taking longer is ended and fails (see harness.sweep.pool)
    look: dict = field(default_factory=dict)     # render.look / look_family / look_seed set on every trial


def protocol_paths(opts: ScorecardOptions) -> list[Path]:
    if opts.protocol_files:
        return [Path(p) for p in opts.protocol_files]
    return [Path(opts.protocol_dir) / f"{s}.yaml" for s in opts.suites]


def variant_for(trial: Trial, opts: ScorecardOptions) -> Variant:
    """The pipeline of a trial: the chosen detector and tracker, the command line's ego-speed stage (the
    warning stage caps closing speeds with it), the warning stage; in the risk suite the Monte Carlo risk
    (its ego model = constant speed when the scenario's ego is known to hold its speed, the ego speed
    from the lane-marking estimator) with the 1/TTC risks scored on the same states."""
    kw = dict(detector=opts.detector, detector_kwargs=dict(opts.detector_kwargs), tracker=opts.tracker,
              warning_kwargs=dict(opts.warning_kwargs), ego_speed=CLI_EGO_SPEED)
    if trial.suite == "risk":
        ego = trial.scenario.get("ego", {})
        constant = ego.get("behaviour") == "constant_speed" and not any(
            e.get("vehicle") == "ego" for e in trial.scenario.get("events", []))
        risk_kwargs = {"n_rollouts": 200, "ego_model": "constant_speed" if constant else "idm"}
        kw.update(risk="monte_carlo", risk_kwargs=risk_kwargs)
    return Variant(name="scorecard", **kw)


def build_tasks(opts: ScorecardOptions) -> tuple[list[Trial], list[RunTask]]:
    """Every trial of the chosen suites and its run task; raises UserError for any bad input."""
    from monorarp.core.errors import UserError
    from monorarp.pipeline.runner import Pipeline

    if opts.trials is not None and opts.trials < 1:
        raise ProtocolError(f"--trials: must be >= 1, got {opts.trials}")
    check_frames(opts.frames, ProtocolError)
    trials: list[Trial] = []
    for path in protocol_paths(opts):
        try:
            is_file = path.is_file()
        except OSError as e:   # e.g. a name too long
            raise ProtocolError(f"{str(path)[:200]}: cannot read protocol ({e.strerror or e})") from None
        if not is_file:
            raise ProtocolError(f"{path}: no such protocol file")
        trials += expand_protocol(load_protocol(path), path, opts.trials)
    tasks, built = [], {}
    for trial in trials:
        try:
            scenario = parse_scenario(trial.scenario, trial.scenario_file).model_dump(mode="json")
            if opts.look:
                scenario["render"] |= opts.look
                scenario = parse_scenario(scenario, trial.scenario_file).model_dump(mode="json")
        except ScenarioError as e:
            raise ProtocolError(f"{trial.scenario_file}: test {trial.test}: {e}") from None
        variant = variant_for(trial, opts)
        config = variant.pipeline_config(Path.cwd())
        pipe = run_mapping(config)
        key = json.dumps(pipe, sort_keys=True)
        if key not in built:      # each distinct pipeline is built once before anything runs
            try:
                Pipeline.from_config(config, parse_scenario(scenario).camera.model())
            except UserError as e:
                raise ProtocolError(f"scorecard pipeline: {e}") from None
            except (TypeError, ValueError) as e:
                raise ProtocolError(f"scorecard pipeline: {type(e).__name__}: {e}") from None
            built[key] = pipe
        rid = sanitize(f"{trial.key}__t{trial.trial}" if trial.kind != "nominal" else f"{trial.key}__seed{trial.trial}")
        tasks.append(RunTask(id=f"{trial.suite}__{rid}", index=len(tasks), scenario_file=trial.scenario_file,
                             scenario_key=trial.suite, seed=int(scenario["seed"]), grid=dict(trial.params),
                             variant=variant.name, scenario=scenario,
                             pipeline=inject_seeds(built[key], int(scenario["seed"])), frames=opts.frames,
                             warning_threshold_s=TTC_CUE_THRESHOLD_S))
    ids = [t.id for t in tasks]
    if len(set(ids)) != len(ids):
        dup = sorted({i for i in ids if ids.count(i) > 1})[0]
        raise ProtocolError(f"two trials get the same run id {dup!r}")
    return trials, tasks


def run_scorecard(out: str | Path, opts: ScorecardOptions, make: Callable[..., Executor] = make_executor) -> dict:
    """Run every trial not already finished, then score and write ``scorecard.json`` and ``report.html``."""
    from harness.scorecard.report import render_scorecard
    from monorarp.app.io import interrupts_deferred, write_atomic, write_json_atomic

    out = Path(out)
    trials, tasks = build_tasks(opts)
    ex = make(opts.executor, opts.workers, opts.address,
              **({} if opts.run_timeout_s is None else {"run_timeout_s": opts.run_timeout_s}))
    getattr(ex, "start", lambda: None)()
    try:
        runs_dir = prepare_out_dir(out, opts.resume)
        execute(ex, [t for t in tasks if not (opts.resume and finished(t, runs_dir))], runs_dir, opts.progress,
                desc="scorecard")
    finally:
        getattr(ex, "close", lambda: None)()
    from harness.sweep.summary import collect_rows, write_summary

    rows = collect_rows(tasks, runs_dir)     # summary.json: what `monorarp check` regression-checks
    card, risk_runs = scorecard(trials, tasks, runs_dir, opts)
    report = render_scorecard(card, score.roc_curves(risk_runs, 2.0))
    with interrupts_deferred():              # summary, scorecard and report: all or none
        write_summary(out, rows, name="scorecard", spec_path=", ".join(map(str, protocol_paths(opts))), grid_keys=[],
                      headline=["warning.first_warning_ttc_s", "warning.episodes", "warning.false_alarms"])
        write_json_atomic(out / SCORECARD_JSON, card, indent=2)
        write_atomic(out / REPORT_HTML, report)
    return card


# ----------------------------------------------------------------------------- scoring
def _frame_arrays(run_dir: Path) -> dict[str, np.ndarray] | None:
    """``per_frame.csv`` -> t, event, and the risk scores (1/TTC, the fcw stage's 1/TTC, the adverse-manoeuvre 1/TTC;
    Monte Carlo where the run has it;
    the true 1/TTC as ``truth_reference``)."""
    try:
        with open(run_dir / "per_frame.csv", newline="") as f:
            rows = list(csv.DictReader(f))
    except OSError:
        return None

    def col(name: str) -> np.ndarray:
        return np.array([float(r[name]) if r[name] not in ("", None) else np.nan for r in rows], dtype=float)

    out = {"t": col("t"), "event": col("risk_event") == 1}
    true_ttc = col("true_min_ttc")     # no estimator: the truth's own 1/TTC, the ceiling of a 1/TTC score
    out["truth_reference"] = np.where(np.isfinite(true_ttc), 1.0 / np.maximum(true_ttc, 1e-3), 0.0)
    if rows and rows[0].get("fcw_ttc_risk") not in ("", None):
        out["fcw_ttc"] = col("fcw_ttc_risk")
    if rows and rows[0].get("manoeuvre_ttc_risk") not in ("", None):
        out["manoeuvre_ttc"] = col("manoeuvre_ttc_risk")
    mc = bool(rows) and rows[0]["risk_kind"] == "probability"
    if mc:
        out["monte_carlo"], out["inverse_ttc"] = col("risk"), col("baseline_ttc_risk")
    else:
        out["inverse_ttc"] = col("risk")
    return out


def scorecard(trials: Sequence[Trial], tasks: Sequence[RunTask], runs_dir: Path, opts: ScorecardOptions
              ) -> tuple[dict, list[dict]]:
    """The ``scorecard.json`` mapping from the runs on disk (see :mod:`harness.scorecard.score`), and the
    risk family's per-frame arrays (for the ROC plot)."""
    groups: dict[tuple[str, str], list[tuple[Trial, RunTask, dict | None, str | None]]] = {}
    failed = []
    fa_episodes, exposure_s, exposure_km, risk_runs = [], 0.0, 0.0, []
    for trial, task in zip(trials, tasks):
        run = read_json_or_none(runs_dir / task.id / RUN_JSON) or {}
        metrics = read_json_or_none(runs_dir / task.id / METRICS_JSON) if run.get("status") == "ok" else None
        if metrics is None:
            failed.append({"id": task.id, "error": run.get("error") or "no result"})
        groups.setdefault((trial.suite, trial.key), []).append((trial, task, metrics, run.get("error")))
        if metrics is None:
            continue
        w = metrics["warning"]
        if trial.kind == "nominal":
            exposure_s += w["exposure_s"]
            exposure_km += w["exposure_km"]
            fa_episodes += [{"run": task.id, "t_s": e["onset_t"], "end_t_s": e["end_t"], "track_id": e["track_id"],
                             "gt_id": e["gt_id"], "true_braking_ttc_s": e.get("true_braking_ttc_s"),
                             "braking": braking_alarm(e, w["threshold_s"]), "why": e["why"]}
                            for e in w["episode_list"] if e["false_alarm"]]
        if trial.suite == "risk":
            arrays = _frame_arrays(runs_dir / task.id)
            if arrays is not None:
                risk_runs.append(arrays)
    tests = []
    for (suite, key), members in groups.items():
        first = members[0][0]
        if first.kind == "nominal":
            continue
        ttcs = [None if m is None else m["warning"]["first_warning_ttc_s"] for _, _, m, _ in members]
        leads = [None if m is None else m["warning"]["lead_time_s"] for _, _, m, _ in members]
        verdicts = [m is not None and score.trial_passed(first.kind, m["warning"], first.required_ttc_s)
                    for _, _, m, _ in members]
        episodes = [None if m is None else m["warning"]["episodes"] for _, _, m, _ in members]
        tests.append({"suite": suite, "test": first.test, "kind": first.kind, "key": key,
                      "ego_speed_mps": first.ego_speed_mps, "target_speed_mps": first.target_speed_mps,
                      "params": {k: v for k, v in first.params.items() if k not in ("target_model_m", "start_gap_m",
                                                                                       "side")},
                      "trials": len(members), "trials_passed": int(sum(verdicts)),
                      "min_trials_passed": first.min_trials_passed, "required_ttc_s": first.required_ttc_s,
                      "ttc_at_first_warning_s": ttcs, "lead_time_s": leads, "episodes": episodes,
                      "runs": [t.id for _, t, _, _ in members],
                      "passed": int(sum(verdicts)) >= first.min_trials_passed})
    hours = exposure_s / 3600.0
    card = {
        "version": 1,
        "config": {"detector": opts.detector, "tracker": opts.tracker, "warning_kwargs": opts.warning_kwargs,
                   "suites": sorted({t.suite for t in trials}), "trials_override": opts.trials,
                   "frames_cap": opts.frames},
        "tests": tests,
        "summary": summary(tests),
        "false_alarms": {"episodes": len(fa_episodes), "hours": hours, "km": exposure_km,
                         "per_hour": len(fa_episodes) / hours if hours > 0 else None,
                         "per_100km": 100 * len(fa_episodes) / exposure_km if exposure_km > 0 else None,
                         "runs": sum(t.kind == "nominal" for t in trials),
                         "warmup_s": sorted({float(t.scenario.get("traffic", {}).get("warmup_s", 0.0))
                                             for t in trials if t.kind == "nominal"}),
                         "braking": sum(e["braking"] for e in fa_episodes), "list": fa_episodes,
                         **rate_fields(len(fa_episodes), hours, exposure_km)},
        "risk": score.pooled_risk(risk_runs) if risk_runs else None,
        "failed_runs": failed,
    }
    from monorarp.app.io import to_jsonable
    return to_jsonable(card), risk_runs


def rate_fields(n: int, hours: float, km: float) -> dict:
    """The false-alarm rate's 95 % Poisson intervals, its target, verdict and the exposure the target needs."""
    lo, hi = score.poisson_interval(n, hours)
    lo_km, hi_km = score.poisson_interval(n, km / 100.0)
    return {"per_hour_ci95": [lo, hi], "per_100km_ci95": [lo_km, hi_km],
            "target_per_hour": score.FALSE_ALARM_TARGET_PER_H, "verdict": score.rate_verdict(n, hours),
            "hours_needed": score.exposure_needed(score.FALSE_ALARM_TARGET_PER_H)}


def summary(tests: Sequence[dict]) -> dict:
    """Headline figures: NHTSA tests passed; share of Euro NCAP runs above 30 km/h warned at TTC >= 2.0 s."""
    out: dict = {}
    nhtsa = [t for t in tests if t["suite"] == "nhtsa"]
    if nhtsa:
        out["nhtsa_passed"] = f"{sum(t['passed'] for t in nhtsa)}/{len(nhtsa)}"
        out["nhtsa_trials_passed"] = f"{sum(t['trials_passed'] for t in nhtsa)}/{sum(t['trials'] for t in nhtsa)}"
    ncap = [v for t in tests if t["suite"] == "ncap" and t["ego_speed_mps"] * 3.6 > 30 + 1e-6
            for v in t["ttc_at_first_warning_s"]]
    if ncap:
        ok = sum(v is not None and v >= 2.0 for v in ncap)
        out["ncap_above_30kmh_ttc_ge_2s"] = ok / len(ncap)
        out["ncap_above_30kmh_runs"] = len(ncap)
        out["ncap_above_30kmh_ttc_ge_2s_ci95"] = list(score.proportion_interval(ok, len(ncap)))
    by_suite: dict = {}
    for t in tests:
        s = by_suite.setdefault(t["suite"], [0, 0])
        s[0] += t["passed"]
        s[1] += 1
    out["tests_passed"] = {k: f"{a}/{b}" for k, (a, b) in by_suite.items()}
    return out
