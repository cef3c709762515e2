"""``monorarp sweep`` end to end: check everything, run what is left, summarise, report.

Layout of ``DIR``::

    DIR/runs/<id>/     one directory per run (see :mod:`harness.sweep.worker`), each written atomically
    DIR/summary.json   DIR/summary.csv   (see :mod:`harness.sweep.summary`)
    DIR/report.html    (see :mod:`harness.sweep.report`)
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

from harness.output import OutputError
from harness.sweep.executors import Executor, make_executor
from harness.sweep.expand import Expansion, RunTask, load_and_expand
from harness.sweep.report import render_report
from harness.sweep.summary import collect_rows, write_summary, write_text_atomic
from harness.sweep.worker import METRICS_JSON, RUN_JSON, RunOutcome

if TYPE_CHECKING:
    from harness.frame_cache import FrameCache

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

    @property
    def failed(self) -> list[dict]:
        return [r for r in self.rows if r["status"] != "ok"]


def finished(task: RunTask, runs_dir: Path) -> bool:
    """Resume rule: ``metrics.json`` exists and ``run.json`` says ok with exactly this task's parameters."""
    d = runs_dir / task.id
    if not (d / METRICS_JSON).is_file():
        return False
    try:
        run = json.loads((d / RUN_JSON).read_text())
    except (OSError, ValueError):
        return False
    return run.get("status") == "ok" and run.get("params") == json.loads(json.dumps(task.params()))


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
    except OSError as e:
        raise OutputError(f"{out}: cannot create output directory ({e.strerror or e})") from None
    return runs


def _progress(total: int, enabled: bool):
    from tqdm import tqdm

    return tqdm(total=total, unit="run", desc="sweep", disable=not enabled, file=sys.stderr, dynamic_ncols=True)


def run_sweep(spec_path: str | Path, out: str | Path, *, executor: str = "local", workers: int = 1,
              resume: bool = False, address: str | None = None, videos: bool = False, progress: bool = True,
              make: Callable[..., Executor] = make_executor,
              cache: FrameCache | Callable[[], FrameCache | None] | None = None) -> SweepResult:
    """Run a sweep; raises :class:`~monorarp.errors.UserError` (nothing run) for a bad spec, output or executor.

    ``cache``: the frame cache every run reads and fills (or a callable giving it, called once the spec
    has been checked); None: every run renders its own frames.
    """
    t0 = time.perf_counter()
    out = Path(out)
    ex = make(executor, workers, address)          # unreachable Ray address etc. fails here, in seconds
    expansion = load_and_expand(spec_path, annotate=videos)
    cache = cache() if callable(cache) else cache   # an unusable cache directory fails here, before any run
    if cache is not None:
        expansion.tasks = [replace(t, cache_dir=str(cache.root), cache_max_bytes=cache.max_bytes)
                           for t in expansion.tasks]
    getattr(ex, "start", lambda: None)()         # e.g. connect to Ray, before DIR is touched
    try:
        return _run(ex, expansion, spec_path, out, resume, progress, t0)
    finally:
        getattr(ex, "close", lambda: None)()


def _run(ex: Executor, expansion: Expansion, spec_path: str | Path, out: Path, resume: bool, progress: bool,
         t0: float) -> SweepResult:
    runs_dir = prepare_out_dir(out, resume)
    tasks = expansion.tasks
    skipped = [t.id for t in tasks if resume and finished(t, runs_dir)]
    todo = [t for t in tasks if t.id not in set(skipped)]
    result = SweepResult(out=out, expansion=expansion, rows=[], skipped=skipped)
    bar = _progress(len(todo), progress)
    try:
        n_failed = 0
        for outcome in ex.run(todo, runs_dir):
            result.executed.append(outcome)
            n_failed += outcome.status != "ok"
            bar.set_postfix_str(f"failed {n_failed}" if n_failed else "", refresh=False)
            bar.update(1)
    finally:
        bar.close()
    spec = expansion.spec
    result.rows = collect_rows(tasks, runs_dir)
    write_summary(out, result.rows, name=spec.name, spec_path=str(spec_path), grid_keys=list(spec.grid),
                  headline=spec.metrics)
    write_text_atomic(out / REPORT_HTML, render_report(result.rows, runs_dir, name=spec.name, spec_path=str(spec_path),
                                                       grid_keys=list(spec.grid), headline=spec.metrics,
                                                       threshold_s=spec.warning_threshold_s))
    result.wall_time_s = time.perf_counter() - t0
    return result
