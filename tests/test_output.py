"""monorarp.app.io: strict JSON, atomic files and atomic output directories."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from monorarp.app.io import JsonlWriter, OutputError, atomic_output_dir, dumps, write_json_atomic


def _strict_loads(text: str):
    def bad(name):
        raise ValueError(f"non-standard JSON constant {name}")
    return json.loads(text, parse_constant=bad)


def test_non_finite_become_null_and_numpy_is_plain(tmp_path):
    obj = {"a": math.nan, "b": [math.inf, -math.inf, 1.5], "c": np.float32(2.5), "d": np.int64(7),
           "e": np.array([[1.0, np.nan]]), "f": (1, 2), "g": np.bool_(True)}
    p = tmp_path / "x.json"
    write_json_atomic(p, obj)
    got = _strict_loads(p.read_text())
    assert got == {"a": None, "b": [None, None, 1.5], "c": 2.5, "d": 7, "e": [[1.0, None]],
                   "f": [1, 2], "g": True}
    assert list(tmp_path.iterdir()) == [p]  # no temp file left
    with pytest.raises(TypeError):
        dumps({"x": object()})


def test_float_round_trip_exact():
    xs = [0.1, 1 / 3, 123456.789012345, 5e-324, -0.0]
    assert _strict_loads(dumps(xs)) == xs


def test_jsonl_writer_commits_on_close_only(tmp_path):
    p = tmp_path / "gt.jsonl"
    with JsonlWriter(p) as w:
        w.write({"frame": 0, "v": math.nan})
        w.write({"frame": 1, "v": 2.0})
        assert not p.exists()  # still a temp file
    lines = p.read_text().splitlines()
    assert [_strict_loads(x) for x in lines] == [{"frame": 0, "v": None}, {"frame": 1, "v": 2.0}]

    q = tmp_path / "bad.jsonl"
    with pytest.raises(RuntimeError):
        with JsonlWriter(q) as w:
            w.write({"frame": 0})
            raise RuntimeError("boom")
    assert not q.exists()
    assert sorted(x.name for x in tmp_path.iterdir()) == ["gt.jsonl"]


def test_atomic_dir_new_target_with_missing_parents(tmp_path):
    target = tmp_path / "a" / "b" / "run"
    with atomic_output_dir(target) as tmp:
        assert tmp.parent == target.parent and not target.exists()
        (tmp / "f.txt").write_text("new")
    assert (target / "f.txt").read_text() == "new"
    assert sorted(x.name for x in target.parent.iterdir()) == ["run"]


def test_atomic_dir_failure_removes_created_parents(tmp_path):
    target = tmp_path / "a" / "b" / "run"
    with pytest.raises(KeyboardInterrupt):
        with atomic_output_dir(target) as tmp:
            (tmp / "f.txt").write_text("partial")
            raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []


def test_atomic_dir_replaces_previous_run_only_on_success(tmp_path):
    target = tmp_path / "run"
    target.mkdir()
    (target / "f.txt").write_text("old")
    with pytest.raises(ValueError):
        with atomic_output_dir(target, owned_names={"f.txt"}) as tmp:
            (tmp / "f.txt").write_text("half")
            raise ValueError("fail mid-run")
    assert (target / "f.txt").read_text() == "old"
    assert sorted(x.name for x in tmp_path.iterdir()) == ["run"]

    with atomic_output_dir(target, owned_names={"f.txt"}) as tmp:
        (tmp / "f.txt").write_text("new")
    assert (target / "f.txt").read_text() == "new"
    assert sorted(x.name for x in tmp_path.iterdir()) == ["run"]  # old copy deleted


def test_atomic_dir_on_a_directory_that_cannot_be_renamed(tmp_path, monkeypatch):
    """A mount point (a container volume) cannot be renamed (EBUSY): its contents are replaced instead."""
    import errno
    import os

    target = tmp_path / "volume"
    target.mkdir()
    (target / "f.txt").write_text("old")
    (target / "sub").mkdir()
    rename = os.rename

    def no_rename_of_target(src, dst):
        if os.fspath(src) == os.fspath(target):
            raise OSError(errno.EBUSY, "Device or resource busy")
        rename(src, dst)

    monkeypatch.setattr(os, "rename", no_rename_of_target)
    with pytest.raises(ValueError):
        with atomic_output_dir(target, owned_names={"f.txt", "sub", "g.txt"}) as tmp:
            assert tmp.parent == target
            (tmp / "f.txt").write_text("half")
            raise ValueError("fail mid-run")
    assert sorted(x.name for x in target.iterdir()) == ["f.txt", "sub"] and (target / "f.txt").read_text() == "old"

    with atomic_output_dir(target, owned_names={"f.txt", "sub", "g.txt"}) as tmp:
        (tmp / "g.txt").write_text("new")
    assert sorted(x.name for x in target.iterdir()) == ["g.txt"]
    assert sorted(x.name for x in tmp_path.iterdir()) == ["volume"]

    (target / "precious.txt").write_text("keep")
    with pytest.raises(OutputError, match="precious.txt"):
        with atomic_output_dir(target, owned_names={"g.txt"}):
            pytest.fail("must not start")


def test_atomic_dir_refuses_foreign_directory_and_files(tmp_path):
    target = tmp_path / "home"
    target.mkdir()
    (target / "precious.txt").write_text("keep")
    with pytest.raises(OutputError, match="precious.txt"):
        with atomic_output_dir(target, owned_names={"f.txt"}):
            pytest.fail("must not start")
    assert (target / "precious.txt").read_text() == "keep"

    f = tmp_path / "file"
    f.write_text("x")
    with pytest.raises(OutputError, match="not a directory"):
        with atomic_output_dir(f):
            pass
    assert sorted(x.name for x in tmp_path.iterdir()) == ["file", "home"]


def test_atomic_dir_refuses_a_symlink_naming_what_it_points_to(tmp_path):
    import os

    (tmp_path / "real").mkdir()
    os.symlink(tmp_path / "real", tmp_path / "link")
    import re

    with pytest.raises(OutputError, match=f"symbolic link.*points to, {re.escape(os.path.realpath(tmp_path / 'real'))}$"):
        with atomic_output_dir(tmp_path / "link"):
            pytest.fail("must not start")
    os.symlink("loop", tmp_path / "loop")
    with pytest.raises(OutputError, match="symbolic link"):
        with atomic_output_dir(tmp_path / "loop"):
            pytest.fail("must not start")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link", "loop", "real"]


def test_atomic_dir_permissions_are_ordinary(tmp_path):
    import os

    mask = os.umask(0o022)
    try:
        with atomic_output_dir(tmp_path / "run") as tmp:
            write_json_atomic(tmp / "c.json", {})
    finally:
        os.umask(mask)
    assert (tmp_path / "run").stat().st_mode & 0o777 == 0o755
    assert (tmp_path / "run" / "c.json").stat().st_mode & 0o777 == 0o644


def test_sigterm_leaves_no_temporary_output(tmp_path):
    """`kill`/`timeout` send SIGTERM: the command unwinds as on Ctrl-C (one line, exit 143, nothing left)."""
    import os
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    out = tmp_path / "r"
    proc = subprocess.Popen([sys.executable, "-m", "monorarp.app.cli", "run", str(root / "scenarios" / "highway_cruise.yaml"),
                             "--out", str(out)], cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            text=True, env={**os.environ, "PYOPENGL_PLATFORM": "egl"})
    deadline = time.monotonic() + 120
    while not any(tmp_path.glob(".r.tmp-*/frames.mp4")) and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)   # the run is writing its frames into its temporary directory
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 128 + signal.SIGTERM, err
    assert err.strip().splitlines() == ["monorarp run: terminated"]
    assert list(tmp_path.iterdir()) == []


def test_interrupts_deferred_holds_ctrl_c_until_the_block_ends():
    import os
    import signal

    from monorarp.app.io import interrupts_deferred

    done = []
    # Python's own Ctrl-C handler, whatever this process inherited (a background job starts with SIGINT ignored)
    inherited = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            with interrupts_deferred():
                os.kill(os.getpid(), signal.SIGINT)
                done.append("first")
                done.append("second")       # not cut between the two
    finally:
        signal.signal(signal.SIGINT, inherited)
    assert done == ["first", "second"]
