"""`monorarp bench trackers` on a tiny scenario: identical inputs for every tracker, output structure, pooling."""

from __future__ import annotations

import json

import motmetrics as mm
import numpy as np
import pytest
import yaml

import harness.run.frame_feed
from harness.bench.trackers import pooled_tracking
from harness.run.oracle import OracleDetector
from monorarp.pipeline import registry
from monorarp.app.cli import main
from monorarp.core.errors import UserError
from monorarp.pipeline.config import ComponentConfig, PipelineConfig
from monorarp.tracking.particle import ParticleTracker
from synthetic import tiny_scenario, vehicle

N_FRAMES = 8
SCENARIO = tiny_scenario("bench_test", 1, [vehicle("lead", 0, 14, 22), vehicle("left", -1, 20, 26)])


class Recording(ParticleTracker):
    """The particle tracker, recording what it is fed."""

    log: dict[str, list] = {}

    def __init__(self, tag: str) -> None:
        super().__init__()
        self.tag = tag
        Recording.log[tag] = []

    def update(self, image, detections, t):
        Recording.log[self.tag].append((id(image), image.copy(), tuple(detections), t))
        return super().update(image, detections, t)


class Forgetful(ParticleTracker):
    """The particle tracker, reporting no track every n-th frame, n = 2, 3, 4, ... for each new instance
    (one per sequence): worse for sure, and by a different margin in each sequence."""

    made = 0

    def __init__(self) -> None:
        super().__init__()
        Forgetful.made += 1
        self.every, self.k = Forgetful.made + 1, 0

    def update(self, image, detections, t):
        tracks = super().update(image, detections, t)
        self.k += 1
        return [] if self.k % self.every == 0 else tracks


@pytest.fixture(scope="module")
def bench(tmp_path_factory):
    base = tmp_path_factory.mktemp("bench")
    scen = base / "tiny.yaml"
    scen.write_text(yaml.safe_dump(SCENARIO))
    calls: list[tuple] = []
    real_detect = OracleDetector.detect

    def counting_detect(self, image):
        out = real_detect(self, image)
        calls.append((id(image), tuple(out)))
        return out

    mp = pytest.MonkeyPatch()
    mp.setattr(OracleDetector, "detect", counting_detect)
    registry.add("tracker", "rec_a", lambda: Recording("a"))
    registry.add("tracker", "rec_b", lambda: Recording("b"))
    out = base / "out"
    try:
        rc = main(["bench", "trackers", "--scenarios", str(scen), "--trackers", "particle,kcf", "rec_a,rec_b",
                   "--detector", "oracle", "--frames", str(N_FRAMES), "--out", str(out)])
    finally:
        mp.undo()
        registry.remove("tracker", "rec_a")
        registry.remove("tracker", "rec_b")
    return rc, out, calls


def test_identical_frames_and_detections(bench):
    rc, _, calls = bench
    assert rc == 0
    assert len(calls) == N_FRAMES                                       # the detector ran once per frame
    a, b = Recording.log["a"], Recording.log["b"]
    assert len(a) == len(b) == N_FRAMES
    for (ia, ima, da, ta), (ib, imb, db, tb), (ic, dc) in zip(a, b, calls):
        assert ia == ib == ic                                           # the very same image object
        np.testing.assert_array_equal(ima, imb)                        # and unchanged by the trackers before
        assert da == db == dc and ta == tb                              # the oracle's detections, as cached
    assert sum(len(d) for _, d in calls) > 0


def test_output_files(bench, capsys):
    _, out, _ = bench
    assert sorted(p.name for p in out.iterdir()) == ["trackers.json", "trackers.md"]
    res = json.loads((out / "trackers.json").read_text())
    assert list(res["trackers"]) == ["particle", "kcf", "rec_a", "rec_b"]
    assert res["config"]["detector"]["name"] == "oracle"
    assert res["config"]["frames_per_scenario"] == {"bench_test": N_FRAMES}
    for name, s in res["trackers"].items():
        assert set(s) >= {"tracker_ms", "detector_ms", "mota", "idf1", "hota", "deta", "assa", "id_switches",
                          "distance_rel_err_median"}
        assert 0.0 <= s["hota"] <= 1.0
        assert s["tracker_ms"]["mean"] > 0 and s["tracker_ms"]["p95"] >= 0
        assert s["detector_ms"] == res["detector_ms"]                   # one shared detector figure
        assert isinstance(s["id_switches"], int)
    # noise-free oracle boxes: the detection-driven trackers are perfect, the distance error small
    for name in ("particle", "rec_a"):
        s = res["trackers"][name]
        assert s["mota"] == pytest.approx(1.0) and s["idf1"] == pytest.approx(1.0) and s["id_switches"] == 0
        assert 0 <= s["distance_rel_err_median"] < 0.05
    for key in ("mota", "idf1", "id_switches", "distance_rel_err_median"):   # same tracker, same inputs
        assert res["trackers"]["rec_a"][key] == res["trackers"]["particle"][key]
    assert res["per_scenario"]["bench_test"]["trackers"]["kcf"]["mota"] is not None
    md = (out / "trackers.md").read_text()
    assert "TABLE III" in md and "| MOTA |" in md and "| HOTA |" in md
    assert all(f"| {n} |" in md for n in res["trackers"])
    # the lead (14 m) and the left car (20 m) each in their range bin; pooled over scenarios
    by = res["trackers"]["particle"]["by_range"]
    assert list(by) == ["0-10", "10-20", "20-40", "40-80"] and by["10-20"]["objects"] > 0
    assert sum(b["objects"] for b in by.values()) == res["trackers"]["particle"]["objects"]
    assert by["10-20"]["mota"] == pytest.approx(1.0) and by["0-10"]["objects"] == 0
    assert "By range of the true distance" in md and "| 10-20 m |" in md
    assert res["bootstrap"] is None and "Uncertainty over sequences" not in md   # too few sequences


def test_unknown_tracker_refused_before_rendering(tmp_path, monkeypatch, capsys):
    def no_render(*a, **k):
        raise AssertionError("rendered")

    monkeypatch.setattr(harness.run.frame_feed, "rendered_frames", no_render)
    scen = tmp_path / "tiny.yaml"
    scen.write_text(yaml.safe_dump(SCENARIO))
    rc = main(["bench", "trackers", "--scenarios", str(scen), "--trackers", "particle,boosting",
               "--detector", "oracle", "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "unknown tracker 'boosting'" in err[0]
    assert not (tmp_path / "out").exists()
    rc = main(["bench", "trackers", "--scenarios", str(tmp_path / "missing.yaml"), "--trackers", "sort",
               "--detector", "oracle", "--out", str(tmp_path / "out")])
    assert rc == 2 and "missing.yaml" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_pooled_by_range_is_each_bins_motmetrics_overall():
    """Each range bin pools like the whole run: motmetrics' OVERALL of that bin's sequences."""
    from harness.bench.trackers import pooled_by_range

    rng = np.random.default_rng(1)
    names = ["mota", "idf1", "idr", "num_switches", "num_false_positives", "num_misses", "num_objects"]
    keys = ["mota", "idf1", "idr", "id_switches", "false_positives", "misses", "objects"]
    bins = {"near": [], "far": []}
    for b in bins:
        for _ in range(2):
            acc = mm.MOTAccumulator(auto_id=True)
            for _ in range(20):
                hyp = list(dict.fromkeys(int(h) for h in rng.integers(0, 5, int(rng.integers(1, 4)))))
                dist = rng.uniform(0, 1, (3, len(hyp)))
                dist[dist > 0.6] = np.nan
                acc.update([0, 1, 2], hyp, dist)
            bins[b].append(acc)
    mh = mm.metrics.create()
    dfs = {b: mh.compute_many(a, metrics=names, names=["s0", "s1"], generate_overall=True) for b, a in bins.items()}
    sections = [{"by_range": {b: dict(zip(keys, dfs[b].loc[s, names])) for b in bins}} for s in ("s0", "s1")]
    pooled = pooled_by_range(sections)
    for b in bins:
        assert pooled[b]["mota"] == pytest.approx(dfs[b].loc["OVERALL", "mota"], abs=1e-12)
        assert pooled[b]["idf1"] == pytest.approx(dfs[b].loc["OVERALL", "idf1"], abs=1e-12)
    assert pooled_by_range([sections[0], {"by_range": None}]) is None


def test_pooled_tracking_matches_motmetrics_overall():
    """Pooling per-sequence counts gives motmetrics' own OVERALL MOTA and IDF1."""
    rng = np.random.default_rng(0)
    accs = []
    for _ in range(3):
        acc = mm.MOTAccumulator(auto_id=True)
        for _ in range(30):
            gt = [i for i in range(4) if rng.random() > 0.1]
            hyp = [int(rng.integers(0, 6)) for _ in range(int(rng.integers(1, 5)))]
            hyp = list(dict.fromkeys(hyp))
            dist = rng.uniform(0, 1, (len(gt), len(hyp)))
            dist[dist > 0.6] = np.nan
            acc.update(gt, hyp, dist)
        accs.append(acc)
    mh = mm.metrics.create()
    names = ["mota", "idf1", "idr", "num_switches", "num_false_positives", "num_misses", "num_objects"]
    df = mh.compute_many(accs, metrics=names, names=["a", "b", "c"], generate_overall=True)
    per = [{"objects": df.loc[n, "num_objects"], "false_positives": df.loc[n, "num_false_positives"],
            "misses": df.loc[n, "num_misses"], "id_switches": df.loc[n, "num_switches"], "idr": df.loc[n, "idr"]}
           for n in "abc"]
    pooled = pooled_tracking(per)
    assert pooled["mota"] == pytest.approx(df.loc["OVERALL", "mota"], abs=1e-12)
    assert pooled["idf1"] == pytest.approx(df.loc["OVERALL", "idf1"], abs=1e-12)
    assert pooled["id_switches"] == df.loc["OVERALL", "num_switches"]


def test_seeds_run_each_scenario_once_per_seed(tmp_path, monkeypatch):
    """``--seeds``: one sequence per scenario and seed, each simulated with that seed, pooled in the totals."""
    scen = tmp_path / "tiny.yaml"
    scen.write_text(yaml.safe_dump({**SCENARIO, "traffic": {"vehicles_count": 3}}))
    seen: list[int] = []
    real = harness.run.frame_feed.rendered_frames

    def recording(scenario, n):
        seen.append(scenario.seed)
        return real(scenario, n)

    monkeypatch.setattr(harness.run.frame_feed, "rendered_frames", recording)
    registry.add("tracker", "forgetful", Forgetful)
    Forgetful.made = 0
    out = tmp_path / "out"
    try:
        rc = main(["bench", "trackers", "--scenarios", str(scen), "--trackers", "particle,forgetful",
                   "--detector", "oracle", "--seeds", "4-7,9", "--frames", "6", "--cache", "off", "--out", str(out)])
    finally:
        registry.remove("tracker", "forgetful")
    assert rc == 0 and seen == [4, 5, 6, 7, 9]
    res = json.loads((out / "trackers.json").read_text())
    names = [f"bench_test seed {k}" for k in (4, 5, 6, 7, 9)]
    assert res["config"]["seeds"] == [4, 5, 6, 7, 9]
    assert res["config"]["frames_per_scenario"] == dict.fromkeys(names, 6)
    per = [res["per_scenario"][n]["trackers"]["particle"] for n in names]
    pooled = res["trackers"]["particle"]
    assert pooled["objects"] == sum(p["objects"] for p in per) > 0
    assert pooled["misses"] == sum(p["misses"] for p in per)
    # the bootstrap resamples these 5 sequences: a pooled ratio over any draw of them lies between the
    # sequences' own values (for the difference too, since both trackers share each sequence's objects)
    boot = res["bootstrap"]
    assert boot["sequences"] == 5 and boot["reference"] == "particle"
    mota = {t: np.array([res["per_scenario"][n]["trackers"][t]["mota"] for n in names]) for t in ("particle", "forgetful")}
    for t, lo_hi in ((t, boot["trackers"][t]["mota"]) for t in mota):
        assert mota[t].min() - 1e-12 <= lo_hi[0] <= res["trackers"][t]["mota"] <= lo_hi[1] <= mota[t].max() + 1e-12
    gap = mota["forgetful"] - mota["particle"]
    lo, hi = boot["trackers"]["forgetful"]["mota_minus_reference"]
    assert gap.min() - 1e-12 <= lo < hi <= gap.max() + 1e-12 and hi < 0 and np.ptp(gap) > 0.1
    assert "mota_minus_reference" not in boot["trackers"]["particle"]
    assert "| forgetful |" in (out / "trackers.md").read_text().split("Uncertainty over sequences")[1]


@pytest.mark.parametrize("seeds", ["5-3", "x", "-1", "2.5"])
def test_bad_seeds_refused_in_one_line(tmp_path, capsys, seeds):
    scen = tmp_path / "tiny.yaml"
    scen.write_text(yaml.safe_dump(SCENARIO))
    rc = main(["bench", "trackers", "--scenarios", str(scen), "--trackers", "sort", "--detector", "oracle",
               f"--seeds={seeds}", "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "--seeds" in err[0] and repr(seeds) in err[0]
    assert not (tmp_path / "out").exists()


def test_default_scenarios_are_found_from_any_directory(tmp_path, monkeypatch):
    """The shipped default scenarios do not depend on the current directory (as the scorecard's suites)."""
    from harness.bench.defaults import DEFAULT_SCENARIOS, default_scenarios

    monkeypatch.chdir(tmp_path)
    assert [p.endswith(s) for p, s in zip(default_scenarios(), DEFAULT_SCENARIOS)] == [True, True]
    assert main(["bench", "trackers", "--trackers", "sort", "--detector", "oracle", "--frames", "2",
                 "--cache", "off", "--out", "out"]) == 0
    res = json.loads((tmp_path / "out" / "trackers.json").read_text())
    assert res["config"]["scenario_names"] == ["highway_cruise", "cut_in"]


@pytest.mark.parametrize("extra, needle", [
    (["--scenarios", "{s},{s}"], "scenario listed twice"),
    (["--scenarios", "{s}", "{d}/../{n}/tiny.yaml"], "scenario listed twice"),
    (["--frames", "100000"], "--frames: 100000 exceeds the scenario's 15 frames"),
    (["--cache", "off", "--cache-max-gb", "nan"], "--cache-max-gb"),
    (["--detector", "centernet", "--weak-detections", "0.2"], "--weak-detections"),
])
def test_bad_bench_requests_refused_in_one_line(tmp_path, capsys, extra, needle):
    scen = tmp_path / "tiny.yaml"
    scen.write_text(yaml.safe_dump(SCENARIO))
    extra = [e.format(s=scen, d=tmp_path, n=tmp_path.name) for e in extra]
    argv = ["bench", "trackers", "--scenarios", str(scen), "--trackers", "sort,kcf", "--detector", "oracle",
            "--frames", "2", *extra, "--out", str(tmp_path / "out")]
    rc = main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and needle in err[0], err
    assert not (tmp_path / "out").exists()


def test_default_frames_still_capped_at_a_short_scenario(tmp_path):
    from harness.bench.trackers import BenchConfig, bench_trackers

    scen = tmp_path / "tiny.yaml"
    scen.write_text(yaml.safe_dump(SCENARIO))            # 15 frames, fewer than the default 90
    res = bench_trackers(BenchConfig(scenarios=[scen], trackers=["sort"], frames=90,
                                     pipeline=PipelineConfig(detector=ComponentConfig(name="oracle"))))
    assert res["config"]["frames_per_scenario"] == {"bench_test": 15}


def test_seeds_limited_to_10000():
    from harness.commands.bench import parse_seeds

    assert len(parse_seeds(["0-9999"])) == 10_000
    with pytest.raises(UserError, match=r"--seeds: at most 10000 seeds, got '1-20000' \(20000 seeds\)"):
        parse_seeds(["1-20000"])
    with pytest.raises(UserError, match="--seeds: at most 10000 seeds in all, got 13002 by '7000-14000'"):
        parse_seeds(["0-6000", "7000-14000"])
