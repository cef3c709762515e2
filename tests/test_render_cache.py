"""The frame cache (harness/run/frame_cache.py): render once per scenario instance, identical results, checked
entries, atomic writes, LRU size limit; the sweep's render-once ordering (RenderOnceQueue)."""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

import harness.run.frame_feed
from harness.run.frame_cache import FRAMES, MANIFEST, TRUTH, FrameCache
from harness.world.scenario import parse_scenario
from harness.sweep.execution import RenderOnceQueue
from harness.sweep.expand import load_and_expand
from monorarp.app.cli import main
from synthetic import tiny_scenario, vehicle

SCENARIO = tiny_scenario("tiny", 0, [vehicle("lead", 0, 13, 17), vehicle("left", -1, 22, 26)], width=160, height=96)
SPEC = {"name": "cache_t", "scenarios": ["tiny.yaml"], "seeds": [1, 2], "frames": 4,
        "variants": [{"name": "pf", "detector": "oracle", "tracker": "particle"},
                     {"name": "sort", "detector": "oracle", "detector_kwargs": {"jitter_px": 1.0}, "tracker": "sort"}]}
SAME_BYTES = ("per_frame.csv", "per_object.csv", "ground_truth.jsonl", "camera.json")
WALL_CLOCK = ("runtime_ms", "fps", "wall_time_s")


@pytest.fixture()
def renders(monkeypatch):
    """Counts calls of harness.run.frame_feed.rendered_frames (the only place frames are made)."""
    calls: list[int] = []
    real = harness.run.frame_feed.rendered_frames

    def counting(scenario, n_frames=None):
        calls.append(scenario.seed)
        return real(scenario, n_frames)

    monkeypatch.setattr(harness.run.frame_feed, "rendered_frames", counting)
    return calls


def tiny(seed: int = 1) -> object:
    return parse_scenario({**SCENARIO, "seed": seed})


def collect(it) -> list[tuple[int, float, np.ndarray, dict]]:
    return [(f.index, f.t, f.image.copy(), truth) for f, truth in it]


def same(a, b) -> bool:
    return len(a) == len(b) and all(x[:2] == y[:2] and np.array_equal(x[2], y[2]) and x[3] == y[3]
                                    for x, y in zip(a, b))


# ------------------------------------------------------------------ byte-identical results
def test_sweep_results_identical_with_cache_off_cold_and_warm(tmp_path, renders):
    (tmp_path / "tiny.yaml").write_text(yaml.safe_dump(SCENARIO))
    spec = tmp_path / "spec.yaml"
    spec.write_text(yaml.safe_dump(SPEC))
    cache = tmp_path / "cache"
    counts = {}
    for name, opt in (("off", "off"), ("cold", str(cache)), ("warm", str(cache))):
        before = len(renders)
        assert main(["sweep", str(spec), "--out", str(tmp_path / name), "--cache", opt, "--no-progress"]) == 0
        counts[name] = len(renders) - before
    assert counts == {"off": 4, "cold": 2, "warm": 0}       # 2 instances (seeds) x 2 variants
    ids = sorted(p.name for p in (tmp_path / "off" / "runs").iterdir())
    assert len(ids) == 4
    for rid in ids:
        runs = [tmp_path / name / "runs" / rid for name in ("off", "cold", "warm")]
        for f in SAME_BYTES:
            first = (runs[0] / f).read_bytes()
            assert all((r / f).read_bytes() == first for r in runs[1:]), (rid, f)
        metrics = [json.loads((r / "metrics.json").read_text()) for r in runs]
        for m in metrics:
            for k in WALL_CLOCK:
                m.pop(k)
        assert metrics[0] == metrics[1] == metrics[2]
    summaries = [json.loads((tmp_path / n / "summary.json").read_text())["counts"] for n in ("off", "cold", "warm")]
    assert summaries[0] == summaries[1] == summaries[2]


def test_bench_trackers_reads_the_same_cache(tmp_path, renders):
    scen = tmp_path / "tiny.yaml"
    scen.write_text(yaml.safe_dump(SCENARIO))
    args = ["bench", "trackers", "--scenarios", str(scen), "--trackers", "particle,sort", "--detector", "oracle",
            "--frames", "3", "--cache", str(tmp_path / "cache")]
    assert main([*args, "--out", str(tmp_path / "a")]) == 0
    assert main([*args, "--out", str(tmp_path / "b")]) == 0
    assert len(renders) == 1
    a, b = (json.loads((tmp_path / d / "trackers.json").read_text()) for d in "ab")
    for r in (a, b):
        for s in r["trackers"].values():
            for k in ("tracker_ms", "detector_ms"):
                s.pop(k)
        r.pop("detector_ms")
        for v in r["per_scenario"].values():
            v.pop("detector_ms")
            for s in v["trackers"].values():
                s.pop("tracker_ms"), s.pop("detector_ms")
    assert a == b


# ------------------------------------------------------------------------ checked entries
def _entry(cache: FrameCache) -> Path:
    (path,) = [p for _, _, p in cache.entries()]
    return path


@pytest.mark.parametrize("damage", ["truncate_frames", "flip_truth_byte", "drop_manifest", "bad_manifest"])
def test_damaged_entry_is_detected_and_rendered_again(tmp_path, renders, damage):
    cache = FrameCache(tmp_path / "cache")
    fresh = collect(cache.frames(tiny(), 3))
    entry = _entry(cache)
    if damage == "truncate_frames":
        data = (entry / FRAMES).read_bytes()
        (entry / FRAMES).write_bytes(data[: len(data) // 2])
    elif damage == "flip_truth_byte":
        data = bytearray((entry / TRUTH).read_bytes())
        i = data.index(b"25.0")                       # same size, different content
        data[i] = ord("3")
        (entry / TRUTH).write_bytes(bytes(data))
    elif damage == "drop_manifest":
        (entry / MANIFEST).unlink()
    else:
        (entry / MANIFEST).write_text("{not json")
    again = collect(cache.frames(tiny(), 3))
    assert cache.last == "rendered" and len(renders) == 2
    assert same(fresh, again)
    assert same(fresh, collect(cache.frames(tiny(), 3))) and cache.last == "hit"   # the entry was replaced


def test_unfinished_render_leaves_no_entry(tmp_path):
    cache = FrameCache(tmp_path / "cache")
    it = cache.frames(tiny(), 4)
    next(it)
    next(it)
    it.close()                                         # the run stopped after 2 frames (error, kill)
    assert cache.entries() == [] and os.listdir(tmp_path / "cache" / "tmp") == []
    assert cache.frames(tiny(), 4) is not None and cache.last == "rendered"


def test_leftovers_of_a_killed_writer_are_removed(tmp_path):
    import socket
    import subprocess
    import sys

    cache = FrameCache(tmp_path / "cache")
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True,
                          text=True, check=True).stdout.strip()
    host = socket.gethostname()
    tmp = tmp_path / "cache" / "tmp"
    for owner in (dead, str(os.getpid())):
        (tmp / f"{'a' * 64}.{host}.{owner}.0badc0de").mkdir(parents=True)
        (tmp / f"{'a' * 64}.{host}.{owner}.0badc0de" / FRAMES).write_bytes(b"half")
    cache.evict()
    assert os.listdir(tmp) == [f"{'a' * 64}.{host}.{os.getpid()}.0badc0de"]   # a live writer's stays


def test_concurrent_writers_of_one_key_one_wins(tmp_path, renders):
    cache = FrameCache(tmp_path / "cache", lock_wait_s=0.1)
    first = cache.frames(tiny(), 3)                    # holds the key's lock while it renders
    head = collect([next(first)])
    other = collect(cache.frames(tiny(), 3))           # lock not granted in time: renders and stores itself
    rest = collect(first)                              # finishes second: its rename loses, its copy is dropped
    assert len(renders) == 2 and same(head + rest, other)
    assert len(cache.entries()) == 1 and os.listdir(tmp_path / "cache" / "tmp") == []
    assert same(other, collect(cache.frames(tiny(), 3))) and cache.last == "hit"


def test_key_follows_content(tmp_path, renders):
    cache = FrameCache(tmp_path / "cache")
    for sc, n in ((tiny(1), 3), (tiny(1), 3), (tiny(2), 3), (tiny(1), 2),
                  (parse_scenario({**SCENARIO, "seed": 1, "camera": {"width": 160, "height": 96, "pitch_deg": 3.0}}), 3)):
        collect(cache.frames(sc, n))
    assert len(renders) == 4 and len(cache.entries()) == 4


# ----------------------------------------------------------------------------- size limit
def test_size_limit_evicts_least_recently_used(tmp_path):
    cache = FrameCache(tmp_path / "cache", max_bytes=None)
    collect(cache.frames(tiny(1), 3))
    ((_, size, _),) = cache.entries()
    cache.max_bytes = int(2.5 * size)                  # room for two entries
    collect(cache.frames(tiny(2), 3))
    time.sleep(0.02)
    collect(cache.frames(tiny(1), 3))                  # seed 1 used again: seed 2 is now the least recent
    assert cache.last == "hit"
    time.sleep(0.02)
    collect(cache.frames(tiny(3), 3))                  # a third entry: one must go
    seeds = sorted(json.loads((p / MANIFEST).read_text())["material"]["scenario"]["seed"] for _, _, p in cache.entries())
    assert seeds == [1, 3]
    cache.max_bytes = 1                                # below one entry: the one just written stays
    collect(cache.frames(tiny(4), 3))
    assert [json.loads((p / MANIFEST).read_text())["material"]["scenario"]["seed"]
            for _, _, p in cache.entries()] == [4]


# ------------------------------------------------------------------------- sweep ordering
def test_render_once_queue_releases_followers_after_their_leader(tmp_path):
    (tmp_path / "tiny.yaml").write_text(yaml.safe_dump(SCENARIO))
    spec = tmp_path / "spec.yaml"
    spec.write_text(yaml.safe_dump(SPEC))
    from dataclasses import replace

    tasks = [replace(t, cache_dir=str(tmp_path)) for t in load_and_expand(spec).tasks]   # seed1 pf, sort, seed2 ...
    q = RenderOnceQueue(tasks)
    assert q.grouped
    a, b = q.next(), q.next()
    assert (a.id, b.id) == (tasks[0].id, tasks[2].id) and q.next() is None   # the two leaders only
    q.done(b)
    assert q.next().id == tasks[3].id and q.next() is None
    q.done(a)
    assert q.next().id == tasks[1].id and q.next() is None
    plain = RenderOnceQueue(load_and_expand(spec).tasks)                      # no cache: all at once, in order
    assert not plain.grouped and [plain.next().id for _ in tasks] == [t.id for t in tasks]


def test_unusable_cache_dir_is_refused_before_any_run(tmp_path, capsys):
    (tmp_path / "tiny.yaml").write_text(yaml.safe_dump(SCENARIO))
    spec = tmp_path / "spec.yaml"
    spec.write_text(yaml.safe_dump(SPEC))
    (tmp_path / "a_file").write_text("x")
    rc = main(["sweep", str(spec), "--out", str(tmp_path / "out"), "--cache", str(tmp_path / "a_file"),
               "--no-progress"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "a_file" in err[0] and not (tmp_path / "out").exists()
    rc = main(["sweep", str(spec), "--out", str(tmp_path / "out"), "--cache-max-gb", "0", "--no-progress"])
    assert rc == 2 and "--cache-max-gb" in capsys.readouterr().err
