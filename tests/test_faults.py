"""`monorarp sweep` under faults: a worker killed mid-run, a hung run, a full disk, a lost Ray
worker, a lost Ray node, the whole sweep killed with ``kill -9``.

Each test injects its fault into a real, tiny sweep (oracle detector, 160x96, 3 frames,
3 runs) through the test-only ``MONORARP_FAULT`` hook (:mod:`harness.sweep.faults`), then
proves that

(a) runs that finished -- before the fault (``DIR`` already held them) or while it
    happened -- are intact (same metrics as a clean sweep) and unchanged (their files
    byte-identical after the fault and after ``--resume``);
(b) the failed run is reported with its cause in ``summary.json``, ``summary.csv``, the
    run's ``run.json`` and the exit status (1), with no partial files anywhere;
(c) ``--resume`` runs only what is unfinished and ends with the same summary (every
    deterministic metric and status) as a clean sweep of the same spec.
"""

from __future__ import annotations

import csv
import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from harness.run.outputs import OUTPUT_NAMES
from harness.check.metrics import deterministic_metrics
from monorarp.app.cli import main

SCENARIO = {
    "name": "tiny", "seed": 0, "duration_s": 1.0, "fps": 15, "road": {"lanes": 3},
    "traffic": {"vehicles_count": 0}, "ego": {"lane": 1, "speed_mps": 25},
    "vehicles": [{"name": "lead", "lane": 0, "distance_m": 13, "speed_mps": 17, "behaviour": "constant_speed"}],
    "camera": {"width": 160, "height": 96},
}
SPEC = {"name": "faults", "scenarios": ["tiny.yaml"], "seeds": [1, 2, 3], "frames": 3,
        "variants": [{"name": "pf", "detector": "oracle", "tracker": "particle"}]}
IDS = ["tiny__seed1__pf", "tiny__seed2__pf", "tiny__seed3__pf"]
FIRST, VICTIM, OTHER = IDS


def write_spec(d: Path) -> Path:
    d.mkdir(parents=True, exist_ok=True)
    (d / "tiny.yaml").write_text(yaml.safe_dump(SCENARIO))
    (d / "spec.yaml").write_text(yaml.safe_dump(SPEC, sort_keys=False))
    return d / "spec.yaml"


def sweep(spec: Path, out: Path, *extra: str) -> int:
    return main(["sweep", str(spec), "--out", str(out), "--cache", "off", "--no-progress", *extra])


def summary(out: Path) -> dict:
    """id -> (status, error, deterministic metrics) from summary.json."""
    return {r["id"]: (r["status"], r["error"], deterministic_metrics(r["metrics"]))
            for r in json.loads((out / "summary.json").read_text())["runs"]}


def file_hashes(out: Path, run_id: str) -> dict[str, str]:
    d = out / "runs" / run_id
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(d.iterdir())}


def leftovers(out: Path) -> list[str]:
    """Temporary files or directories anywhere under ``out`` (half-written output)."""
    return sorted(str(p.relative_to(out)) for p in out.rglob(".*"))


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    """The spec and a clean sweep of it (the reference every faulty sweep must end up equal to)."""
    d = tmp_path_factory.mktemp("faults")
    spec = write_spec(d)
    assert sweep(spec, d / "clean") == 0
    clean = summary(d / "clean")
    assert [s for s, _, _ in clean.values()] == ["ok"] * 3
    assert all(m["frames"] == 3 for _, _, m in clean.values())
    return spec, d / "clean", clean


def prefilled(case, out: Path) -> dict[str, str]:
    """``out`` holding FIRST as finished by an earlier sweep; returns FIRST's file hashes."""
    spec, clean_dir, _ = case
    shutil.copytree(clean_dir / "runs" / FIRST, out / "runs" / FIRST)
    return file_hashes(out, FIRST)


def check_failed_then_resume(case, out: Path, cause: str, before: dict[str, dict[str, str]], capsys) -> None:
    """(a), (b), (c) of the module docstring for a sweep in ``out`` where VICTIM failed with ``cause``."""
    spec, _, clean = case
    assert cause in capsys.readouterr().out                      # "FAILED <id>: <cause>" on stdout
    got = summary(out)
    status, error, _ = got[VICTIM]
    assert status == "failed" and cause in error
    rows = {r["id"]: r for r in csv.DictReader((out / "summary.csv").open())}
    assert rows[VICTIM]["status"] == "failed" and cause in rows[VICTIM]["error"]
    run = json.loads((out / "runs" / VICTIM / "run.json").read_text())
    assert run["status"] == "failed" and cause in run["error"]
    assert sorted(p.name for p in (out / "runs" / VICTIM).iterdir()) == ["error.json", "run.json"]
    assert leftovers(out) == []
    finished = {rid: file_hashes(out, rid) for rid in IDS if rid != VICTIM}
    for rid in finished:                                           # (a) intact: as in a clean sweep
        assert got[rid] == clean[rid]
    for rid, h in before.items():                                  # (a) unchanged by the fault
        assert finished[rid] == h
    assert sweep(spec, out, "--resume") == 0                       # (c)
    assert "2 skipped (already finished)" in capsys.readouterr().out   # only VICTIM ran again
    assert summary(out) == clean
    for rid, h in finished.items():                                # (a) unchanged by the resume
        assert file_hashes(out, rid) == h
    assert leftovers(out) == []


def fault_then_resume(case, tmp_path, monkeypatch, capsys, fault, message):
    """FIRST prefilled, a two-worker --resume sweep under MONORARP_FAULT=`fault` fails (rc 1), then resumes."""
    out = tmp_path / "out"
    before = {FIRST: prefilled(case, out)}
    monkeypatch.setenv("MONORARP_FAULT", fault)
    assert sweep(case[0], out, "--resume", "--workers", "2") == 1
    monkeypatch.delenv("MONORARP_FAULT")
    check_failed_then_resume(case, out, message, before, capsys)


def test_worker_killed_mid_run(case, tmp_path, monkeypatch, capsys):
    """SIGKILL of a worker process after it wrote its run's files, before it committed them."""
    fault_then_resume(case, tmp_path, monkeypatch, capsys, f"kill:{VICTIM}",
                      "worker process died (killed by SIGKILL)")


def test_native_crash_is_retried_once(case, tmp_path, monkeypatch, capsys):
    """A worker that segfaults (a fault in a C library) gets its run retried in a new worker:
    the sweep ends as a clean one, with the crash said on stderr."""
    out = tmp_path / "out"
    before = {FIRST: prefilled(case, out)}
    monkeypatch.setenv("MONORARP_FAULT", f"segv_once:{VICTIM}")
    assert sweep(case[0], out, "--resume", "--workers", "2") == 0
    err = capsys.readouterr().err
    assert f"run {VICTIM}: worker process died (killed by SIGSEGV); retried once in a new worker" in err
    assert summary(out) == case[2]
    assert file_hashes(out, FIRST) == before[FIRST]
    assert leftovers(out) == []


def test_native_crash_twice_fails_the_run(case, tmp_path, monkeypatch, capsys):
    """A run whose worker crashes again in the retry fails with the cause; --resume completes it."""
    fault_then_resume(case, tmp_path, monkeypatch, capsys, f"segv:{VICTIM}",
                      "worker process died (killed by SIGSEGV), twice")


def test_hung_run_times_out(case, tmp_path, monkeypatch, capsys):
    """A run that never returns is ended by --run-timeout; the other worker's run goes on."""
    out = tmp_path / "out"
    before = {FIRST: prefilled(case, out)}
    monkeypatch.setenv("MONORARP_FAULT", f"hang:{VICTIM}")
    t0 = time.monotonic()
    assert sweep(case[0], out, "--resume", "--workers", "2", "--run-timeout", "15") == 1
    assert time.monotonic() - t0 < 120
    monkeypatch.delenv("MONORARP_FAULT")
    check_failed_then_resume(case, out, "timeout after 15 s", before, capsys)


@pytest.mark.parametrize("free_bytes", [0, 2500])
def test_full_disk_while_writing(case, tmp_path, monkeypatch, capsys, free_bytes):
    """ENOSPC part-way through the run's outputs (0 bytes free, or a few files' worth)."""
    out = tmp_path / "out"
    before = {FIRST: prefilled(case, out)}
    monkeypatch.setenv("MONORARP_FAULT", f"enospc={free_bytes}:{VICTIM}")
    assert sweep(case[0], out, "--resume") == 1
    monkeypatch.delenv("MONORARP_FAULT")
    err = json.loads((out / "runs" / VICTIM / "error.json").read_text())
    assert "Errno 28" in err["error"] and "OSError" in err["traceback"]
    named = err["error"].split("while writing ", 1)[1].split(" ", 1)[0]
    assert named in OUTPUT_NAMES                       # 0 bytes: camera.json; 2500: metrics.json (today)
    check_failed_then_resume(case, out, "no space left on device while writing", before, capsys)


def test_ray_worker_lost(case, tmp_path, monkeypatch, capsys):
    """A Ray worker process dies mid-task (as when its node goes away): that task fails, the others finish."""
    pytest.importorskip("ray", reason="Ray is not installed (optional extra: pip install '.[ray]')")
    out = tmp_path / "out"
    before = {FIRST: prefilled(case, out)}
    monkeypatch.setenv("MONORARP_FAULT", f"kill:{VICTIM}")
    assert sweep(case[0], out, "--resume", "--executor", "ray", "--workers", "2") == 1
    monkeypatch.delenv("MONORARP_FAULT")
    check_failed_then_resume(case, out, "ray task failed: The worker died", before, capsys)


@pytest.mark.slow
def test_ray_node_lost(case, tmp_path, monkeypatch, capsys):
    """A whole Ray node goes away mid-sweep (``ray.cluster_utils.Cluster``: a head without CPUs and
    two 1-CPU nodes on this machine). VICTIM hangs; once the other runs are written both worker
    nodes are removed: VICTIM fails with Ray's node-death cause, nothing else is lost."""
    pytest.importorskip("ray", reason="Ray is not installed (optional extra: pip install '.[ray]')")
    import threading

    from ray.cluster_utils import Cluster

    out = tmp_path / "out"
    before = {FIRST: prefilled(case, out)}
    monkeypatch.setenv("MONORARP_FAULT", f"hang:{VICTIM}")
    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 0})
    try:
        nodes = [cluster.add_node(num_cpus=1) for _ in range(2)]
        cluster.wait_for_nodes()
        removed = threading.Event()

        def lose_nodes() -> None:
            deadline = time.monotonic() + 240
            while not (out / "runs" / OTHER / "run.json").is_file() and time.monotonic() < deadline:
                time.sleep(0.2)
            for n in nodes:
                cluster.remove_node(n)
            removed.set()

        threading.Thread(target=lose_nodes, daemon=True).start()
        assert sweep(case[0], out, "--resume", "--executor", "ray", "--address", cluster.address) == 1
        assert removed.is_set()
    finally:
        cluster.shutdown()
    monkeypatch.delenv("MONORARP_FAULT")
    check_failed_then_resume(case, out, "the node it was running on is dead", before, capsys)


def _children(pid: int) -> list[int]:
    kids = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            kids.append(int(stat.parent.name))
    return kids


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
def test_sweep_killed_with_kill_9_then_resumed(case, tmp_path, capsys):
    """``kill -9`` of the sweep while VICTIM hangs and two runs have finished: the finished runs stay
    byte-identical, the workers die with the sweep, ``--resume`` runs exactly the unfinished one."""
    spec, _, clean = case
    out = tmp_path / "out"
    env = {**os.environ, "MONORARP_FAULT": f"hang:{VICTIM}"}
    cmd = [sys.executable, "-m", "monorarp.app.cli", "sweep", str(spec), "--out", str(out), "--cache", "off",
           "--no-progress", "--workers", "2"]
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    workers: list[int] = []
    try:
        deadline = time.monotonic() + 240
        while not all((out / "runs" / rid / "run.json").is_file() for rid in (FIRST, OTHER)):
            assert proc.poll() is None and time.monotonic() < deadline, "the sweep ended or stalled"
            time.sleep(0.2)
        workers = _children(proc.pid)
        before = {rid: file_hashes(out, rid) for rid in (FIRST, OTHER)}
        proc.send_signal(signal.SIGKILL)
        proc.wait(30)
        deadline = time.monotonic() + 30
        while any(map(_alive, workers)) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert workers and not any(map(_alive, workers)), "worker processes outlived the killed sweep"
    finally:
        if proc.poll() is None:
            proc.kill()
        for pid in workers:
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)
    assert not (out / "runs" / VICTIM).exists()            # nothing of the killed run under its name,
    assert any(f"runs/.{VICTIM}.tmp-" in p for p in leftovers(out))   # only its half-done temporary dir
    assert not (out / "summary.json").exists()
    for rid, h in before.items():
        assert file_hashes(out, rid) == h
    assert sweep(spec, out, "--resume") == 0
    assert "3/3 runs ok, 2 skipped (already finished)" in capsys.readouterr().out   # exactly VICTIM ran
    assert summary(out) == clean
    for rid, h in before.items():
        assert file_hashes(out, rid) == h
    assert leftovers(out) == []


# ------------------------------------------------------- the driver's own disk, bad options
def test_summary_on_a_full_disk_is_one_line_and_resumable(case, tmp_path, monkeypatch, capsys):
    """The disk fills while the summary is written: one line naming the cause, exit 2, finished runs
    intact and no partial summary; once space is back, --resume writes it without running anything."""
    import harness.sweep.orchestrate as orch
    from harness.sweep.faults import full_disk

    spec, clean_dir, clean = case
    out = tmp_path / "out"
    for rid in IDS:
        shutil.copytree(clean_dir / "runs" / rid, out / "runs" / rid)
    before = {rid: file_hashes(out, rid) for rid in IDS}
    real = orch.write_summary

    def write_summary_on_full_disk(*a, **kw):
        with full_disk(100):
            return real(*a, **kw)

    monkeypatch.setattr(orch, "write_summary", write_summary_on_full_disk)
    assert sweep(spec, out, "--resume") == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "no space left on device while writing summary.json" in err
    assert "--resume" in err and "3 finished runs" in err
    assert not (out / "summary.json").exists() and leftovers(out) == []
    monkeypatch.setattr(orch, "write_summary", real)
    assert sweep(spec, out, "--resume") == 0
    assert "3 skipped" in capsys.readouterr().out and summary(out) == clean
    assert {rid: file_hashes(out, rid) for rid in IDS} == before


def test_a_failure_record_refused_by_a_full_disk_still_reaches_the_summary(case, tmp_path, monkeypatch):
    """A worker died and the disk refuses its run.json: the summary carries the cause from memory."""
    from harness.sweep import pool, worker
    from harness.sweep.expand import load_and_expand
    from harness.sweep.faults import full_disk
    from harness.sweep.orchestrate import with_outcomes
    from harness.sweep.summary import collect_rows

    task = next(t for t in load_and_expand(case[0]).tasks if t.id == VICTIM)
    (tmp_path / "runs").mkdir()
    real = worker.write_run_files

    def refused(*a, **kw):
        with full_disk(0):
            return real(*a, **kw)

    monkeypatch.setattr(worker, "write_run_files", refused)
    outcome = pool.record_failure(task, tmp_path / "runs", pool.death_cause(-signal.SIGKILL))
    assert outcome.status == "failed" and "killed by SIGKILL" in outcome.error
    assert "could not be written (no space left on device while writing run.json" in outcome.error
    assert list((tmp_path / "runs").iterdir()) == []                  # nothing partial
    rows = with_outcomes(collect_rows([task], tmp_path / "runs"), [outcome])
    assert rows[0]["status"] == "failed" and rows[0]["error"] == outcome.error


def test_leftovers_of_a_killed_sweep_are_removed_and_a_renamed_run_restored(tmp_path):
    """What a kill between atomic renames leaves: temp dirs go, a finished run renamed away comes back."""
    from harness.sweep.orchestrate import clean_leftovers

    runs = tmp_path / "runs"
    (runs / "a").mkdir(parents=True)
    (runs / ".a.tmp-x1y2z3").mkdir()
    (runs / "..a.tmp-x1y2z3.tmp-q9").mkdir()
    (runs / ".b.old-0123abcd").mkdir()
    (runs / ".b.old-0123abcd" / "metrics.json").write_text("{}")
    (runs / ".a.old-89abcdef").mkdir()               # a's new version did arrive: the old one is garbage
    assert sorted(clean_leftovers(runs)) == ["..a.tmp-x1y2z3.tmp-q9", ".a.old-89abcdef", ".a.tmp-x1y2z3"]
    assert sorted(p.name for p in runs.iterdir()) == ["a", "b"]
    assert (runs / "b" / "metrics.json").read_text() == "{}"


@pytest.mark.parametrize("value", ["0", "-3", "nan", "inf"])
def test_bad_run_timeout_is_refused(case, tmp_path, capsys, value):
    out = tmp_path / "out"
    assert sweep(case[0], out, "--run-timeout", value) == 2
    assert main(["scorecard", "--out", str(out), "--run-timeout", value, "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all("--run-timeout" in line for line in err) and not out.exists()


def test_fault_hook_is_inert_unless_set(monkeypatch):
    from harness.sweep import faults

    monkeypatch.delenv(faults.ENV, raising=False)
    assert faults.planned(VICTIM) is None
    monkeypatch.setenv(faults.ENV, f"hang:{OTHER}, enospc=12:{VICTIM}")
    assert faults.planned(VICTIM) == ("enospc", 12) and faults.planned(OTHER) == ("hang", 0)
    assert faults.planned(FIRST) is None
    monkeypatch.setenv(faults.ENV, f"explode:{VICTIM}")
    with pytest.raises(ValueError, match="MONORARP_FAULT"):
        faults.planned(VICTIM)


def test_scorecard_passes_run_timeout_to_its_executor(tmp_path):
    from harness.scorecard.run import ScorecardOptions, run_scorecard
    from harness.sweep.executors import ExecutorError, make_executor
    from harness.sweep.pool import ProcessExecutor

    seen = {}

    def make(*args, **kw):
        seen["executor"] = make_executor(*args, **kw)
        raise ExecutorError("stop here")

    with pytest.raises(ExecutorError):
        run_scorecard(tmp_path / "out", ScorecardOptions(suites=("nominal",), detector="oracle", run_timeout_s=7.5),
                      make=make)
    ex = seen["executor"]
    assert isinstance(ex, ProcessExecutor) and ex.workers == 1 and ex.run_timeout_s == 7.5
    assert not (tmp_path / "out").exists()
