"""``monorarp sweep`` end to end: check everything, run what is left, summarise, report.

Layout of ``DIR``::

    DIR/runs/<id>/     one directory per run (see :mod:`harness.sweep.worker`), each written atomically
    DIR/summary.json   DIR/summary.csv   (see :mod:`harness.sweep.summary`)
    DIR/report.html    (see :mod:`harness.sweep.report`)

Faults: a run whose worker dies or overruns ``--run-timeout`` is recorded as failed
with its cause (see :mod:`harness.sweep.pool`); runs that finished are never
rewritten. After a ``kill -9`` of the sweep itself, ``--resume`` removes what the
killed sweep left half-done (:func:`clean_leftovers`) and runs exactly the runs
that are not finished.
"""

from __future__ import annotations

import json
import re
import shutil
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

from harness.sweep.executors import Executor, make_executor
from harness.sweep.expand import Expansion, RunTask, load_and_expand
from harness.sweep.report import render_report
from harness.sweep.summary import collect_rows, write_summary
from harness.sweep.worker import METRICS_JSON, RUN_JSON, RunOutcome, describe_error
from monorarp.app.io import OutputError, interrupts_deferred, write_atomic
from monorarp.core.readers import read_json_or_none

if TYPE_CHECKING:
    from harness.run.frame_cache import FrameCache

RUNS = "runs"
REPORT_HTML = "report.html"
OUR_NAMES = {RUNS, "summary.json", "summary.csv", REPORT_HTML, "scorecard.json"}   # sweeps and scorecards


@dataclass
class SweepResult:
    out: Path
    expansion: Expansion
    rows: list[dict]
    skipped: list[str] = field(default_factory=list)
    executed: list[RunOutcome] = field(default_factory=list)
    wall_time_s: float = 0.0
    checks: list | None = None       # harness.check.baseline.CheckRow per check, with a baseline

    @property
    def regressions(self) -> list:
        return [c for c in self.checks or [] if c.failed]

    @property
    def failed(self) -> list[dict]:
        return [r for r in self.rows if r["status"] != "ok"]


def finished(task: RunTask, runs_dir: Path) -> bool:
    """Resume rule: ``metrics.json`` exists and ``run.json`` says ok with exactly this task's parameters."""
    d = runs_dir / task.id
    if not (d / METRICS_JSON).is_file():
        return False
    run = read_json_or_none(d / RUN_JSON)
    if not isinstance(run, dict):
        return False
    return run.get("status") == "ok" and run.get("params") == json.loads(json.dumps(task.params()))


_OLD = re.compile(r"^\.(?P<id>[^.].*)\.old-[0-9a-f]{8}$")


def clean_leftovers(runs_dir: Path) -> list[str]:
    """Remove the temporary directories of runs that never committed (a killed worker or sweep).

    A run directory renamed away for replacement (``.ID.old-*``) whose new version never
    arrived is renamed back, so a finished run is never lost. Returns the names removed.
    """
    removed: list[str] = []
    for p in sorted(runs_dir.iterdir()) if runs_dir.is_dir() else ():
        if not p.name.startswith(".") or (".tmp-" not in p.name and ".old-" not in p.name):
            continue
        m = _OLD.match(p.name)
        if m and ".tmp-" not in m["id"] and p.is_dir() and not (runs_dir / m["id"]).exists():
            p.rename(runs_dir / m["id"])
            continue
        shutil.rmtree(p, ignore_errors=True) if p.is_dir() else p.unlink(missing_ok=True)
        removed.append(p.name)
    return removed


def prepare_out_dir(out: Path, resume: bool) -> Path:
    if out.exists() and not out.is_dir():
        raise OutputError(f"{out}: output path exists and is not a directory")
    if out.is_dir() and not resume:
        present = sorted(p.name for p in out.iterdir())
        if present:
            raise OutputError(f"{out}: not empty ({', '.join(present[:3])}{' ...' if len(present) > 3 else ''}); "
                              f"pass --resume to continue a sweep there, or choose another --out")
    if out.is_dir() and resume:
        foreign = sorted(p.name for p in out.iterdir() if p.name not in OUR_NAMES and not p.name.startswith("."))
        if foreign:
            raise OutputError(f"{out}: holds files a sweep did not write ({', '.join(foreign[:3])}); "
                              f"choose another --out")
    runs = out / RUNS
    try:
        runs.mkdir(parents=True, exist_ok=True)
        if resume:
            clean_leftovers(runs)
            for p in out.glob(".*.tmp"):       # a summary or report being written when the sweep was killed
                p.unlink(missing_ok=True)
    except OSError as e:
        raise OutputError(f"{out}: cannot create output directory ({e.strerror or e})") from None
    return runs


def refuse_runs_not_in_spec(runs_dir: Path, ids: set[str]) -> None:
    """``--resume`` continues one sweep: run directories the spec does not have (another spec's, or runs
    dropped from this one) would sit beside a summary that omits them, so they are refused, not deleted."""
    other = sorted(p.name for p in runs_dir.iterdir() if not p.name.startswith(".") and p.name not in ids)
    if other:
        raise OutputError(f"{runs_dir}: {len(other)} run(s) not in this spec ({', '.join(other[:3])}"
                          f"{' ...' if len(other) > 3 else ''}); remove them to resume with this spec, "
                          f"or choose another --out")


def execute(ex: Executor, todo: Sequence[RunTask], runs_dir: Path, progress: bool,
            desc: str = "sweep") -> list[RunOutcome]:
    """Run ``todo`` on ``ex`` under a progress bar named ``desc`` (the command); return the outcomes in order.

    However it ends (Ctrl-C and SIGTERM included) the workers are ended first, then what they left
    unfinished is removed (:func:`clean_leftovers`); finished runs stay.
    """
    bar = _progress(len(todo), progress, desc)
    outcomes = ex.run(todo, runs_dir)
    executed: list[RunOutcome] = []
    n_failed = 0
    try:
        for outcome in outcomes:
            executed.append(outcome)
            n_failed += outcome.status != "ok"
            bar.set_postfix_str(f"failed {n_failed}" if n_failed else "", refresh=False)
            bar.update(1)
    finally:
        getattr(outcomes, "close", lambda: None)()
        bar.close()
        clean_leftovers(runs_dir)
    return executed


def with_outcomes(rows: list[dict], executed: list[RunOutcome]) -> list[dict]:
    """Rows whose run left no record on disk (e.g. a full disk refused it) take this sweep's outcome."""
    failed = {o.id: o.error for o in executed if o.status != "ok"}
    for r in rows:
        if r["status"] == "missing" and r["id"] in failed:
            r["status"], r["error"] = "failed", failed[r["id"]] or "failed"
    return rows


def _progress(total: int, enabled: bool, desc: str = "sweep"):
    from tqdm import tqdm

    return tqdm(total=total, unit="run", desc=desc, disable=not enabled, file=sys.stderr, dynamic_ncols=True)


def run_sweep(spec_path: str | Path, out: str | Path, *, executor: str = "local", workers: int = 1,
              resume: bool = False, address: str | None = None, videos: bool = False, progress: bool = True,
              make: Callable[..., Executor] = make_executor,
              cache: FrameCache | Callable[[], FrameCache | None] | None = None,
              run_timeout_s: float | None = None, baseline: Mapping | None = None,
              baseline_path: str | None = None) -> SweepResult:
    """Run a sweep; raises :class:`~monorarp.core.errors.UserError` (nothing run) for a bad spec, output or executor.

    ``baseline`` (:func:`harness.check.baseline.load_baseline`'s mapping, read from ``baseline_path``): the
    rows are regression-checked against it (``result.checks``) and the verdict heads ``report.html``.

    ``run_timeout_s``: a run taking longer (seconds of wall time) is ended and recorded as failed.

    ``cache``: the frame cache every run reads and fills (or a callable giving it, called once the spec
    has been checked); None: every run renders its own frames.
    """
    t0 = time.perf_counter()
    out = Path(out)
    limit = {} if run_timeout_s is None else {"run_timeout_s": run_timeout_s}
    ex = make(executor, workers, address, **limit)  # unreachable Ray address etc. fails here, in seconds
    expansion = load_and_expand(spec_path, annotate=videos)
    cache = cache() if callable(cache) else cache   # an unusable cache directory fails here, before any run
    if cache is not None:
        expansion.tasks = [replace(t, cache_dir=str(cache.root), cache_max_bytes=cache.max_bytes)
                           for t in expansion.tasks]
    getattr(ex, "start", lambda: None)()         # e.g. connect to Ray, before DIR is touched
    try:
        return _run(ex, expansion, spec_path, out, resume, progress, t0, baseline, baseline_path)
    finally:
        getattr(ex, "close", lambda: None)()


def _run(ex: Executor, expansion: Expansion, spec_path: str | Path, out: Path, resume: bool, progress: bool,
         t0: float, baseline: Mapping | None = None, baseline_path: str | None = None) -> SweepResult:
    runs_dir = prepare_out_dir(out, resume)
    tasks = expansion.tasks
    if resume:
        refuse_runs_not_in_spec(runs_dir, {t.id for t in tasks})
    skipped = [t.id for t in tasks if resume and finished(t, runs_dir)]
    todo = [t for t in tasks if t.id not in set(skipped)]
    result = SweepResult(out=out, expansion=expansion, rows=[], skipped=skipped)
    result.executed = execute(ex, todo, runs_dir, progress)
    spec = expansion.spec
    result.rows = with_outcomes(collect_rows(tasks, runs_dir), result.executed)
    if baseline is not None:
        from harness.check.baseline import RunResult, compare

        result.checks = compare(baseline, {r["id"]: RunResult(r["status"], r.get("error"), dict(r["metrics"]))
                                           for r in result.rows})
    report = render_report(result.rows, runs_dir, name=spec.name, spec_path=str(spec_path), grid_keys=list(spec.grid),
                           headline=spec.metrics, threshold_s=spec.warning_threshold_s, checks=result.checks,
                           baseline_path=baseline_path)
    try:
        with interrupts_deferred():          # the summary and its report: both or neither
            write_summary(out, result.rows, name=spec.name, spec_path=str(spec_path), grid_keys=list(spec.grid),
                          headline=spec.metrics)
            write_atomic(out / REPORT_HTML, report)
    except OSError as e:
        n_ok = sum(r["status"] == "ok" for r in result.rows)
        raise OutputError(f"{out}: cannot write the summary ({describe_error(e)}); the {n_ok} finished runs under "
                          f"{runs_dir} are intact: free space, then rerun with --resume") from None
    result.wall_time_s = time.perf_counter() - t0
    return result
