"""Every reader of a user file, fed generated malformed documents through the CLI (hypothesis).

For each reader -- scenario YAML (``render``, ``run``, ``bench trackers``), sweep spec
(``sweep``), camera file (``video``, ``calibrate-horizon``), baseline / ``metrics.json`` /
``summary.json`` / ``run.json`` (``check``), FCW protocol (``scorecard --protocol``), ONNX
model and its sidecar JSON (``run --detector``), video file and input string (``video``,
``calibrate-horizon``) -- :mod:`tests.fuzz_docs` generates malformed documents and the
test calls :func:`monorarp.app.cli.main` in-process, asserting what a user would see:
exit status 2, exactly one line on stderr naming the command and the file, no
traceback (an uncaught exception fails the test), and nothing written.

A generated document that happens to be *valid* is skipped (``assume``) before the
command is run, so no test ever simulates or renders; each test checks that with
the loader the command uses. The readers that accept almost any JSON (``metrics.json``,
``run.json``, ``summary.json``) and the video files get documents that are invalid by
construction (``documents(..., breaks=...)``, :func:`_video_bytes`), so that nearly every
example reaches the command as a malformed document; what such a reader accepts is fuzzed
apart (:func:`test_check_lenient_results`).

Examples per test: ``MONORARP_FUZZ_EXAMPLES`` (default 60, about 20 s for the file on
2 cores); ``benchmarks/fuzz_count.py`` runs them with 10,000 and prints the number of
malformed documents each reader was given (:data:`COUNTS`, written to
``MONORARP_FUZZ_COUNTS`` when set). CI runs are derandomized (same examples every
run); set ``MONORARP_FUZZ_RANDOM=1`` for fresh ones.
"""

from __future__ import annotations

import collections
import json
import os
import shutil
import tempfile
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, assume, given, note, settings
from hypothesis import strategies as st

from fuzz_docs import NOT_JSON, Doc, documents, materialise, plausible_json, scalars, to_json
from monorarp.app.cli import main
from monorarp.core.errors import UserError
from monorarp.core.readers import MAX_JSON_BYTES

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = int(os.environ.get("MONORARP_FUZZ_EXAMPLES", "60"))
FUZZ = settings(max_examples=EXAMPLES, deadline=None, database=None,
                derandomize=not os.environ.get("MONORARP_FUZZ_RANDOM"),
                suppress_health_check=list(HealthCheck))
#: Malformed documents each reader was given (valid ones skipped before this count).
COUNTS: collections.Counter = collections.Counter()

SCENARIO = {"name": "fuzz", "seed": 3, "duration_s": 1.0, "fps": 15,
            "road": {"lanes": 3, "lane_width_m": 4.0, "markings": {"stripe_length_m": 3.05, "period_m": 12.19}},
            "traffic": {"vehicles_count": 0, "density": 1.0, "speed_range_mps": [20, 30],
                        "idm": {"a_max": 3.0}, "mobil": {"politeness": 0.0}},
            "ego": {"lane": 1, "speed_mps": 25.0, "behaviour": "constant_speed"},
            "vehicles": [{"name": "lead", "lane": 0, "distance_m": 40.0, "speed_mps": 25.0, "behaviour": "idm"},
                         {"name": "left", "lane": -1, "distance_m": 25.0, "speed_mps": 26.0,
                          "length_m": 5.0, "width_m": 2.0, "lateral_offset_m": 0.0}],
            "events": [{"type": "brake", "vehicle": "lead", "at_s": 0.5, "decel_mps2": 7.0, "until_speed_mps": 0.0},
                       {"type": "speed_change", "vehicle": "ego", "at_s": 0.2, "target_speed_mps": 20.0}],
            "camera": {"width": 320, "height": 180, "hfov_deg": 70.0, "height_m": 1.3, "pitch_deg": 2.0},
            "render": {"palette_seed": 0, "light_direction": [-0.4, 0.3, -1.0]},
            "end_on_contact_s": None}
SPEC = {"name": "fuzz", "scenarios": ["quick.yaml", {"file": "quick.yaml", "overrides": {"duration_s": 0.5}}],
        "seeds": [1, 2], "grid": {"camera.pitch_deg": [1, 3], "vehicles.lead.speed_mps": [20.0]},
        "overrides": {"fps": 15}, "frames": 3, "warning_threshold_s": 2.0,
        "metrics": ["distance.rel_err_median", "tracking.mota"],
        "variants": [{"name": "p", "detector": "oracle", "tracker": "particle"},
                     {"name": "s", "detector": "oracle", "tracker": "sort", "velocity": "difference"}]}
PROTOCOL = {"suite": "fuzz", "description": "d", "trials": 1, "fps": 15, "camera": {"width": 320, "height": 180},
            "tests": [{"test": "LVS", "kind": "rear_end", "target_motion": "stationary", "ego_speed_kmh": [72.36],
                       "target_speed_kmh": 0, "required_ttc_s": 2.1},
                      {"test": "LVD", "kind": "rear_end", "target_motion": "braking", "ego_speed_kmh": [72.36],
                       "target_speed_kmh": 72.36, "gap_m": [30.0], "target_decel_mps2": [2.94], "brake_at_s": 2.0,
                       "required_ttc_s": 2.4},
                      {"test": "CutIn", "kind": "cut_in", "ego_speed_kmh": [90], "target_speed_kmh": 72,
                       "gap_m": [12.0], "required_ttc_s": 1.0, "lateral_offset": [0.0], "adjacent_traffic": [0, 2]}]}
CAMERA = {"width": 640, "height": 360, "fx": 457.0, "fy": 457.0, "cx": 319.5, "cy": 179.5, "height_m": 1.3,
          "pitch_rad": 0.0349, "lateral_offset_m": 0.0, "forward_offset_m": 0.5,
          "K": [[457.0, 0.0, 319.5], [0.0, 457.0, 179.5], [0.0, 0.0, 1.0]], "horizon_row": 163.5}
CAMERA_YAML = {"width": 640, "height": 360, "hfov_deg": 70.0, "height_m": 1.3, "pitch_deg": 2.0}
METRICS = {"frames": 15, "distance": {"rel_err_median": 0.05, "by_range": {"0-10": {"count": 3}}},
           "tracking": {"mota": 0.9, "idf1": 0.8, "id_switches": 0}, "runtime_ms": {"total": 20.0},
           "config": {"components": {"detector": "oracle"}}}
BASELINE = {"version": 1, "comment": "fuzz",
            "defaults": [{"metric": "frames", "tolerance": 0, "direction": "two_sided"},
                         {"metric": "tracking.*", "tolerance": 0.05, "direction": "higher_is_better",
                          "rel_tolerance": 0.01}],
            "runs": {"r1": {"frames": {"value": 15.0, "tolerance": 0.0, "direction": "two_sided"},
                            "distance.rel_err_median": {"value": 0.05, "tolerance": 0.01,
                                                        "direction": "lower_is_better"},
                            "tracking.mota": {"value": 0.9}}}}
SUMMARY = {"name": "fuzz", "spec": "x.yaml", "runs": [{"id": "r1", "status": "ok", "error": None,
                                                       "metrics": {"frames": 15, "tracking.mota": 0.9}},
                                                      {"id": "r2", "status": "failed", "error": "boom",
                                                       "metrics": {}}]}
RUN_JSON = {"id": "r1", "status": "ok", "params": {"seed": 1}}
SIDECAR = json.loads((ROOT / "monorarp" / "models" / "centernet_vehicle.json").read_text())
SHIPPED_MODEL = ROOT / "monorarp" / "models" / "centernet_vehicle.onnx"


# ------------------------------------------------------------------------------ helpers
@pytest.fixture(scope="module")
def base(tmp_path_factory):
    """Shared valid files: a tiny scenario, a camera, a small decodable video; per-example dirs live under it."""
    d = tmp_path_factory.mktemp("fuzz")
    (d / "quick.yaml").write_text(yaml.safe_dump({"name": "quick", "duration_s": 1.0,
                                                  "traffic": {"vehicles_count": 0},
                                                  "camera": {"width": 160, "height": 90}}))
    (d / "camera.yaml").write_text(yaml.safe_dump(CAMERA_YAML))
    # the camera's size, so that no "intrinsics scaled" note precedes the error line
    writer = cv2.VideoWriter(str(d / "clip.mp4"), cv2.VideoWriter_fourcc(*"mp4v"), 15.0, (640, 360))
    ramp = np.linspace(0, 255, 640).astype(np.int64)[None, :, None]
    for i in range(8):
        writer.write(np.broadcast_to((ramp + 8 * i) % 256, (360, 640, 3)).astype(np.uint8))
    writer.release()
    assert (d / "clip.mp4").stat().st_size > 0
    # the video faults damage these boxes (_video_bytes); the frames come before them
    boxes = {kind: off for off, _, kind in mp4_boxes((d / "clip.mp4").read_bytes())}
    assert set(SAMPLE_TABLE_BOXES) <= set(boxes) and boxes[b"moov"] > boxes[b"mdat"], boxes
    yield d
    if os.environ.get("MONORARP_FUZZ_COUNTS"):
        Path(os.environ["MONORARP_FUZZ_COUNTS"]).write_text(json.dumps(dict(sorted(COUNTS.items())), indent=1))


def _workdir(base: Path) -> Path:
    return Path(tempfile.mkdtemp(dir=base, prefix="case-"))


def _tree(d: Path) -> list:
    return sorted((str(p.relative_to(d)), p.is_dir(), p.is_file() and p.stat().st_size)
                  for p in d.rglob("*") if not p.is_symlink())


def invoke(argv: list[str], capsys) -> tuple[int, str, str]:
    """``main(argv)`` -> (status, stdout, stderr); any exception escaping main is what a user sees as a traceback."""
    capsys.readouterr()
    try:
        rc = main(argv)
    except SystemExit as e:   # argparse
        rc = e.code if isinstance(e.code, int) else 2
    except BaseException as e:  # noqa: BLE001
        out = capsys.readouterr()
        pytest.fail(f"traceback: {type(e).__name__}: {e!s:.500} (argv {argv!r:.300}; stderr {out.err!r:.300})")
    got = capsys.readouterr()
    return rc, got.out, got.err


def assert_one_line_error(rc: int, out: str, err: str, command: str, names: list[str]) -> None:
    note(f"rc={rc} stdout={out[-500:]!r} stderr={err[-1000:]!r}")
    assert "Traceback" not in out + err
    assert rc == 2, f"exit status {rc}, expected 2"
    assert out.strip() == "", "an error case printed to stdout"
    lines = err.strip().splitlines()
    assert len(lines) == 1, f"{len(lines)} lines on stderr"
    assert lines[0].startswith(f"monorarp {command}: error: ")
    assert any(n in lines[0] for n in names), f"error does not name any of {names}: {lines[0]}"


def assert_nothing_written(work: Path, before: list, out: Path | None = None) -> None:
    if out is not None:
        assert not out.exists(), f"{out} was written"
    assert _tree(work) == before, "files appeared or changed in the working directory"


def rejected_without_writing(work: Path, capsys, argv_for, command: str, names: list[str]) -> None:
    """``monorarp <argv_for(out)>`` (out = work/out) fails with a one-line error naming one of ``names`` and
    writes nothing, neither ``out`` nor anything in ``work``; then ``work`` is removed."""
    out = work / "out"
    before = _tree(work)
    rc, o, e = invoke(argv_for(out), capsys)
    assert_one_line_error(rc, o, e, command, names)
    assert_nothing_written(work, before, out)
    shutil.rmtree(work)


def valid_with(loader, *args) -> bool:
    """True when ``loader(*args)`` accepts the input; False for a UserError; an unexpected exception counts as
    not valid (the CLI call then shows it)."""
    try:
        loader(*args)
    except UserError:
        return False
    except Exception:  # noqa: BLE001 - surfaced by the CLI call
        return False
    return True


def names_for(path: Path) -> list[str]:
    return [str(path), path.name[:60], repr(str(path))[:60]]


# ------------------------------------------------------------------------------ scenario
@FUZZ
@given(doc=documents(SCENARIO, "yaml"), command=st.sampled_from(["render", "run", "bench"]))
def test_scenario_file(base, capsys, doc: Doc, command: str):
    from harness.world.scenario import load_scenario

    work = _workdir(base)
    path = materialise(doc, work, "scenario.yaml")
    assume(not valid_with(load_scenario, path))
    COUNTS["scenario"] += 1
    rejected_without_writing(work, capsys, lambda out: {
        "render": ["render", str(path), "--out", str(out)],
        "run": ["run", str(path), "--out", str(out), "--detector", "oracle"],
        "bench": ["bench", "trackers", "--scenarios", str(path), "--trackers", "sort", "--detector", "oracle",
                  "--out", str(out)]}[command], "bench" if command == "bench" else command, names_for(path))


# ------------------------------------------------------------------------------ sweep spec
@FUZZ
@given(doc=documents(SPEC, "yaml"))
def test_sweep_spec(base, capsys, doc: Doc):
    from harness.sweep.expand import load_and_expand

    work = _workdir(base)
    shutil.copy(base / "quick.yaml", work / "quick.yaml")
    path = materialise(doc, work, "spec.yaml")
    assume(not valid_with(load_and_expand, path))
    COUNTS["sweep spec"] += 1
    # a spec's error may name a scenario file it references instead of the spec itself
    rejected_without_writing(work, capsys, lambda out: ["sweep", str(path), "--out", str(out), "--no-progress"],
                             "sweep", names_for(path) + ["quick.yaml", "--out"])


# ------------------------------------------------------------------------------ protocol
@FUZZ
@given(doc=documents(PROTOCOL, "yaml"))
def test_protocol_file(base, capsys, doc: Doc):
    from harness.scorecard.run import ScorecardOptions, build_tasks

    work = _workdir(base)
    path = materialise(doc, work, "protocol.yaml")
    opts = ScorecardOptions(protocol_files=(path,), detector="oracle", tracker="sort", progress=False)
    assume(not valid_with(build_tasks, opts))
    COUNTS["protocol"] += 1
    rejected_without_writing(work, capsys, lambda out: ["scorecard", "--protocol", str(path), "--detector", "oracle",
                                                        "--tracker", "sort", "--out", str(out), "--no-progress"],
                             "scorecard", names_for(path))


# ------------------------------------------------------------------------------ camera
camera_docs = st.one_of(st.tuples(documents(CAMERA, "json", with_fs=False), st.just(".json")),
                        st.tuples(documents(CAMERA_YAML, "yaml"), st.sampled_from([".yaml", ".yml"])))


@FUZZ
@given(doc_suffix=camera_docs, command=st.sampled_from(["video", "calibrate-horizon"]))
def test_camera_file(base, capsys, doc_suffix: tuple[Doc, str], command: str):
    from monorarp.core.camera import CameraModel

    doc, suffix = doc_suffix
    work = _workdir(base)
    path = materialise(doc, work, "camera" + suffix)
    assume(not valid_with(CameraModel.load, path))
    COUNTS["camera"] += 1
    out = work / "out"
    before = _tree(work)
    argv = [command, str(base / "clip.mp4"), "--camera", str(path)]
    if command == "video":
        argv += ["--out", str(out), "--detector", "oracle-not-registered"]
    rc, o, e = invoke(argv, capsys)
    assert_one_line_error(rc, o, e, command, names_for(path))
    assert_nothing_written(work, before, out)
    shutil.rmtree(work)


# ------------------------------------------------------------------------------ check
def _results_dir(work: Path, metrics: bytes | None = None, run_json: bytes | None = None) -> Path:
    r = work / "r1"
    r.mkdir()
    (r / "metrics.json").write_bytes(metrics if metrics is not None else to_json(METRICS, 2))
    if run_json is not None:
        (r / "run.json").write_bytes(run_json)
    return r


def _check_outcome(rc, o, e, work, before, names, malformed: bool) -> None:
    note(f"rc={rc} stdout={o[-500:]!r} stderr={e[-1000:]!r}")
    if malformed:
        assert_one_line_error(rc, o, e, "check", names)
    else:   # accepted: a table and exit 0/1, never a traceback
        assert "Traceback" not in o + e and rc in (0, 1) and e == ""
    assert_nothing_written(work, before)


@FUZZ
@given(doc=documents(BASELINE, "json", limit=MAX_JSON_BYTES), update=st.booleans())
def test_check_baseline(base, capsys, doc: Doc, update: bool):
    from harness.check.baseline import load_baseline

    work = _workdir(base)
    results = _results_dir(work)
    path = materialise(doc, work, "baseline.json")
    malformed = not valid_with(load_baseline, path)
    assume(malformed)
    COUNTS["baseline"] += 1
    before = _tree(work)
    rc, o, e = invoke(["check", str(results), "--baseline", str(path)] + (["--update"] if update else []), capsys)
    if update and doc.kind not in ("bytes", "sparse", "directory"):
        # --update where no baseline exists writes a new one (valid use); a name too long fails in one line
        assert "Traceback" not in o + e and rc in (0, 2) and len(e.strip().splitlines()) == (rc == 2)
    else:
        _check_outcome(rc, o, e, work, before, names_for(path), malformed)
    shutil.rmtree(work)


def _not_an_object(value) -> st.SearchStrategy:
    """The document a list, a string, a number, ... instead of an object (``check`` reads objects only)."""
    return st.one_of(st.just([value]), scalars, st.lists(scalars, max_size=3))


@st.composite
def _summary_fault(draw, value):
    """``value`` (a mutated summary) with one fault ``check`` refuses: no ``runs`` list, a run that is not an
    object or has no ``id``, a run's ``metrics`` that is neither an object nor empty."""
    if not isinstance(value, dict):
        return value                      # refused already
    runs = value.get("runs")
    fault = draw(st.sampled_from(["no runs", "runs not a list"] + ["run not an object", "run without id",
                                  "metrics not an object"] * (isinstance(runs, list) and bool(runs))))
    if fault == "no runs":
        value.pop("runs", None)
    elif fault == "runs not a list":
        value["runs"] = draw(st.one_of(scalars, st.dictionaries(st.text(max_size=6), scalars, max_size=3)))
    else:
        run = draw(st.sampled_from(range(len(runs))))
        if fault == "run not an object":
            runs[run] = draw(st.one_of(scalars, st.lists(scalars, max_size=3)))
        elif isinstance(runs[run], dict) and fault == "run without id":
            runs[run].pop("id", None)   # (or gone already)
        elif isinstance(runs[run], dict):    # (a run that is no object is refused already)
            runs[run]["metrics"] = draw(st.one_of(st.lists(scalars, min_size=1, max_size=3), st.text(min_size=1),
                                                  st.integers().filter(bool), st.just(True),
                                                  st.floats().filter(bool)))
    return value


def _check_results(base: Path, capsys, doc: Doc, which: str) -> bool:
    """``check`` of a results directory whose ``which`` (metrics.json, run.json, summary.json) is ``doc``: one
    line and exit 2 if the reader refuses it, a table and exit 0/1 if not. Returns whether it was refused."""
    from harness.check.baseline import load_results

    work = _workdir(base)
    if which == "summary.json":
        results = work / "sweep"
        results.mkdir()
    else:
        results = _results_dir(work, run_json=to_json(RUN_JSON, 2))
        (results / which).unlink()
    path = materialise(doc, results, which)
    baseline = work / "baseline.json"
    baseline.write_bytes(to_json(BASELINE, 2))
    malformed = not valid_with(load_results, results)
    note(f"malformed={malformed}")
    before = _tree(work)
    rc, o, e = invoke(["check", str(results), "--baseline", str(baseline)], capsys)
    _check_outcome(rc, o, e, work, before, names_for(path) + names_for(results), malformed)
    shutil.rmtree(work)
    return malformed


# a valid document that slips through is run all the same (accepted: a table), but not counted
@FUZZ
@given(doc=documents(METRICS, "json", limit=MAX_JSON_BYTES, breaks=(_not_an_object,)))
def test_check_metrics_json(base, capsys, doc: Doc):
    COUNTS["metrics.json"] += _check_results(base, capsys, doc, "metrics.json")


@FUZZ
@given(doc=documents(RUN_JSON, "json", limit=MAX_JSON_BYTES, with_fs=False, breaks=()))
def test_check_run_json(base, capsys, doc: Doc):
    """``run.json`` is optional and any JSON value (only its ``id`` is used): unreadable JSON is the fault."""
    COUNTS["run.json"] += _check_results(base, capsys, doc, "run.json")


@FUZZ
@given(doc=documents(SUMMARY, "json", limit=MAX_JSON_BYTES, breaks=(_not_an_object, _summary_fault)))
def test_check_summary_json(base, capsys, doc: Doc):
    COUNTS["summary.json"] += _check_results(base, capsys, doc, "summary.json")


@FUZZ
@given(which_doc=st.sampled_from([("metrics.json", METRICS), ("run.json", RUN_JSON), ("summary.json", SUMMARY)])
       .flatmap(lambda wb: st.tuples(st.just(wb[0]), plausible_json(wb[1]))))
def test_check_lenient_results(base, capsys, which_doc: tuple[str, Doc]):
    """Wrong types, missing and extra keys, ... that the results readers mostly accept: a table and exit 0/1
    (a metric that is no number is "changed"), or one line if refused; never a traceback. Not counted."""
    _check_results(base, capsys, which_doc[1], which_doc[0])


def test_not_json_tokens_are_no_json():
    """The tokens that make a lenient reader's documents invalid are no JSON wherever they stand."""
    for token in NOT_JSON:
        for text in (token, f"[{token}]", f"[1, {token}, 2]", f'{{"a": {token}}}', f'{{"a": {token}, "b": 1}}'):
            with pytest.raises(ValueError):
                json.loads(text)


# ------------------------------------------------------------------------------ ONNX models
def _onnx_model(inputs: list[tuple[str, list, int]], outputs: list[tuple[str, list]], opset: int) -> bytes:
    import onnx
    from onnx import TensorProto, helper

    nodes, outs = [], []
    for name, shape in outputs:
        value = np.zeros([max(int(d), 1) if isinstance(d, int) else 1 for d in shape], np.float32)
        nodes.append(helper.make_node("Constant", [], [name], value=onnx.numpy_helper.from_array(value, name + "_v")))
        outs.append(helper.make_tensor_value_info(name, TensorProto.FLOAT, shape))
    ins = [helper.make_tensor_value_info(n, t, s) for n, s, t in inputs]
    graph = helper.make_graph(nodes, "fuzz", ins, outs)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", opset)])
    model.ir_version = 8
    return model.SerializeToString()


dims = st.one_of(st.integers(1, 300), st.sampled_from([0, "N", "h"]))
tiny_models = st.builds(
    _onnx_model,
    st.lists(st.tuples(st.sampled_from(["images", "input", "x"]), st.lists(dims, min_size=0, max_size=5),
                       st.sampled_from([1, 1, 10, 7, 11])), min_size=0, max_size=2, unique_by=lambda t: t[0]),
    st.lists(st.tuples(st.sampled_from(["heatmap", "ltrb", "output0", "boxes", "y"]),
                       st.lists(st.integers(1, 90), min_size=1, max_size=4)), min_size=1, max_size=3,
             unique_by=lambda t: t[0]),
    st.integers(13, 17),
).map(lambda b: Doc("bytes", b, "tiny onnx"))


@st.composite
def damaged_shipped_model(draw) -> Doc:
    data = bytearray(SHIPPED_MODEL.read_bytes())
    op = draw(st.sampled_from(["truncate", "flip_header", "flip_anywhere", "insert"]))
    if op == "truncate":
        data = data[:draw(st.integers(0, len(data) - 1))]
    elif op == "flip_header":
        for _ in range(draw(st.integers(1, 6))):
            data[draw(st.integers(0, 4096))] = draw(st.integers(0, 255))
    elif op == "flip_anywhere":
        for _ in range(draw(st.integers(1, 6))):
            data[draw(st.integers(0, len(data) - 1))] = draw(st.integers(0, 255))
    else:
        i = draw(st.integers(0, len(data)))
        data[i:i] = draw(st.binary(min_size=1, max_size=32))
    return Doc("bytes", bytes(data), f"shipped:{op}")


onnx_docs = st.one_of(tiny_models, tiny_models, damaged_shipped_model(),
                      st.binary(max_size=4096).map(lambda b: Doc("bytes", b, "binary")),
                      st.sampled_from(["missing", "directory", "long_name", "symlink_loop", "dangling_symlink"]
                                      ).map(lambda k: Doc(k, b"", k)))
sidecar_docs = documents(SIDECAR, "json", with_fs=False).map(lambda d: Doc(d.kind, d.data, "sidecar:" + d.label))


@FUZZ
@given(doc=onnx_docs, suffix=st.sampled_from([".onnx", ".ONNX"]))
def test_onnx_model_path(base, capsys, doc: Doc, suffix: str):
    _onnx_case(base, capsys, doc, suffix)


@FUZZ
@given(doc=sidecar_docs)
def test_onnx_sidecar_json(base, capsys, doc: Doc):
    """The shipped model with a malformed ``<model>.json`` (stride, score threshold, ...) beside it."""
    _onnx_case(base, capsys, doc, ".onnx")


def _onnx_case(base, capsys, doc: Doc, suffix: str):
    from monorarp.pipeline.detectors import load_detector

    work = _workdir(base)
    shutil.copy(base / "quick.yaml", work / "quick.yaml")
    if doc.label.startswith("sidecar:"):     # the shipped model with a malformed <model>.json beside it
        path = work / f"model{suffix}"
        os.symlink(SHIPPED_MODEL, path)
        side = materialise(doc, work, "model.json")
        names = names_for(side) + names_for(path)   # a stride that does not fit the model names the model
    else:
        path = materialise(doc, work, f"model{suffix}")
        names = names_for(path)
    assume(not valid_with(load_detector, str(path)))
    COUNTS["onnx model" if not doc.label.startswith("sidecar:") else "onnx sidecar json"] += 1
    out = work / "out"
    before = _tree(work)
    rc, o, e = invoke(["run", str(work / "quick.yaml"), "--detector", str(path), "--out", str(out), "--no-video"],
                      capsys)
    assert_one_line_error(rc, o, e, "run", names)
    assert_nothing_written(work, before, out)
    shutil.rmtree(work)


# ------------------------------------------------------------------------------ videos
@st.composite
def video_docs(draw) -> Doc:
    kind = draw(st.sampled_from(["truncated", "flipped", "binary", "header+junk", "fs", "text"]))
    if kind == "fs":
        return Doc(draw(st.sampled_from(["missing", "directory", "long_name", "symlink_loop"])), b"", "fs")
    if kind == "binary":
        return Doc("bytes", draw(st.binary(min_size=1, max_size=8192)), kind)
    if kind == "text":
        return Doc("bytes", draw(st.text(min_size=1, max_size=200)).encode("utf-8", "surrogatepass"), kind)
    return Doc("bytes", b"", kind + f":{draw(st.integers(0, 2 ** 31))}")


#: The MP4 boxes (ISO/IEC 14496-12) that lead the demuxer to the frames: the track and its sample table. A
#: damaged type of any of them leaves no decodable frame (measured: none of the 8,160 one-byte changes of the
#: test clip's eight type fields opens; a damaged moov or minf may still open: FFmpeg reads hoov, dinf, sinf).
SAMPLE_TABLE_BOXES = (b"trak", b"mdia", b"stbl", b"stsd", b"stts", b"stsc", b"stsz", b"stco")
_CONTAINER_BOXES = (b"moov", b"trak", b"mdia", b"minf", b"stbl")


def mp4_boxes(data: bytes, start: int = 0, end: int | None = None) -> list[tuple[int, int, bytes]]:
    """(offset, size, type) of every box of an MP4 file, walking into the containers on the way to the sample
    table (a box: 32-bit big-endian size, 4-byte type)."""
    end = len(data) if end is None else end
    out = []
    while start + 8 <= end:
        size, kind = int.from_bytes(data[start:start + 4], "big"), data[start + 4:start + 8]
        if size < 8:
            break
        out.append((start, size, kind))
        if kind in _CONTAINER_BOXES:
            out += mp4_boxes(data, start + 8, start + size)
        start += size
    return out


def _video_bytes(doc: Doc, clip: bytes) -> Doc:
    """Mutations of the real clip are made here (the clip exists only once the fixture ran). Each leaves no
    decodable frame by construction: a cut before the end of the sample table (the clip's moov box, which holds
    it, comes after the frames), bytes flipped anywhere plus the type of one sample-table box, or the header
    followed by junk."""
    if doc.label.startswith(("truncated", "flipped", "header+junk")):
        rng = np.random.default_rng(int(doc.label.split(":")[1]))
        data = bytearray(clip)
        table = [(off, size) for off, size, kind in mp4_boxes(clip) if kind in SAMPLE_TABLE_BOXES]
        if doc.label.startswith("truncated"):
            data = data[:int(rng.integers(1, max(off + size for off, size in table)))]
        elif doc.label.startswith("flipped"):
            for i in rng.integers(0, len(data), int(rng.integers(1, 40))):
                data[i] = int(rng.integers(0, 256))
            i = table[int(rng.integers(len(table)))][0] + 4 + int(rng.integers(4))    # a byte of the box type
            data[i] = (clip[i] + int(rng.integers(1, 256))) % 256
        else:
            data = data[:64] + bytearray(rng.integers(0, 256, int(rng.integers(1, 20000)), dtype=np.uint8).tobytes())
        return Doc("bytes", bytes(data), doc.label)
    return doc


@FUZZ
@given(doc=video_docs(), command=st.sampled_from(["video", "calibrate-horizon"]))
def test_video_file(base, capsys, doc: Doc, command: str):
    from monorarp.app.video.source import VideoSource

    work = _workdir(base)
    doc = _video_bytes(doc, (base / "clip.mp4").read_bytes())
    path = materialise(doc, work, "input.mp4")

    def opens(p):      # `video` decodes the first frame, then checks the detector; calibrate-horizon reads on
        with VideoSource(p) as s:
            if command == "calibrate-horizon":
                list(s.frames(4))

    decodable = valid_with(opens, path)
    COUNTS["video file"] += not decodable
    out = work / "out"
    before = _tree(work)
    argv = [command, str(path), "--camera", str(base / "camera.yaml")]
    argv += ["--out", str(out), "--detector", "not-a-detector"] if command == "video" else ["--frames", "4"]
    rc, o, e = invoke(argv, capsys)
    if decodable:    # it decodes: `video` stops at the unknown detector, calibrate-horizon may even succeed
        assert "Traceback" not in o + e and rc in (0, 2)
        lines = e.strip().splitlines()
        if rc == 2:      # an informational note (e.g. "intrinsics scaled to the video") may precede the error
            assert lines[-1].startswith(f"monorarp {command}: error: ")
            assert all(ln.startswith("note: ") for ln in lines[:-1]), lines
    else:            # a first frame that decodes may get its "note: ... scaled" before decoding fails later
        e = "".join(ln for ln in e.splitlines(keepends=True) if not ln.startswith("note: "))
        assert_one_line_error(rc, o, e, command, names_for(path))
    assert_nothing_written(work, before, out)
    shutil.rmtree(work)


input_strings = st.one_of(
    st.text(alphabet=st.characters(blacklist_categories=("Cs",), blacklist_characters="\x00"), max_size=300),
    st.from_regex(r"\A[0-9]{1,40}\Z"), st.from_regex(r"\A-?[0-9]{1,12}\Z"),
    st.sampled_from(["/dev/null", "/dev/zero", "/proc/self/mem", "/", ".", "..", "~", "*", " 0", "0 ", "00",
                     "file:///etc/passwd", "http://127.0.0.1:1/x.mp4", "rtsp://127.0.0.1:1/s", "x" * 5000,
                     "%d.png", "img_%03d.jpg", "v4l2:///dev/video0", "-", "--", "9" * 5000]))


@FUZZ
@given(spec=input_strings)
def test_video_input_string(base, capsys, spec: str):
    assume(not spec.startswith("-") or spec.lstrip("-").isdigit())   # options are argparse's business
    assume(spec.strip() not in ("0",) and not (spec.strip().isdigit() and len(spec.strip().lstrip("0")) == 1))
    work = _workdir(base)
    out = work / "out"
    before = _tree(work)
    COUNTS["video input string"] += 1
    rc, o, e = invoke(["video", spec, "--camera", str(base / "camera.yaml"), "--out", str(out),
                       "--detector", "not-a-detector"], capsys)
    norm = lambda t: " ".join(t.split())[:8]  # noqa: E731  (the CLI folds whitespace into single spaces)
    assert_one_line_error(rc, o, e, "video", [norm(spec), norm(repr(spec)[1:]), norm(str(Path(spec))), "webcam",
                                              "not-a-detector"])
    assert_nothing_written(work, before, out)
    shutil.rmtree(work)


# ------------------------------------------------------------------------------ limits, stated once
def test_limits_are_documented_values():
    """The readers' limits docs/formats.md states (a change here is a change there)."""
    from monorarp.core import readers

    assert readers.MAX_CONFIG_BYTES == 256 << 10 and readers.MAX_JSON_BYTES == 256 << 20
    assert readers.MAX_DEPTH == 64 and readers.MAX_NODES == 100_000 and readers.MAX_INT_BITS == 256
    text = (Path(__file__).resolve().parents[1] / "docs" / "formats.md").read_text(encoding="utf-8")
    limits = text[text.index("## Limits of the readers"):]
    for stated in ("**256 KiB**", "**256 MiB**", "**64**", "**100,000**", "256 bits"):
        assert stated in limits, stated


@pytest.mark.parametrize("text, message", [
    ("a: &a [1, 2]\nb: [*a, *a]\n", None),                                # aliases within limits still work
    ("d: 2024-01-01\n", None),                                            # dates stay strings
    ("[" * 65 + "]" * 65, "nested more than 64 levels deep"),
    ("x: !!python/object/apply:os.system ['true']", "could not determine a constructor"),
    ("x: !!bool maybe", "invalid YAML"),
    ("a: &a [*a]", "recursive alias"),
    ("a: 1\nb: 2\na: 3\n", r"^f\.yaml: invalid YAML at line 3: duplicate key 'a' \(first at line 1\)$"),
    ("a:\n  - {x: 1, y: 2, x: 1}\n", "line 2: duplicate key 'x'"),
    ("a: &m {x: 1}\nb: {<<: *m, x: 2}\n", None),                        # a merge's keys may be overridden
])
def test_yaml_reader_cases(tmp_path, text, message):
    from monorarp.core.readers import parse_yaml

    if message is None:
        data = parse_yaml(text, "f.yaml")
        assert json.loads(json.dumps(data)) == data
        return
    with pytest.raises(UserError, match=message):
        parse_yaml(text, "f.yaml")


def test_camera_file_with_a_duplicate_key_names_it(tmp_path):
    import re

    from monorarp.core.camera import CameraError, CameraModel

    cam = tmp_path / "cam.yaml"
    cam.write_text(yaml.safe_dump(CAMERA_YAML, sort_keys=False) + "height_m: 9.0\n")
    line = len(cam.read_text().splitlines())
    with pytest.raises(CameraError, match=rf"^{re.escape(str(cam))}: .*line {line}: duplicate key 'height_m' \(first at line 4\)"):
        CameraModel.load(cam)


@pytest.mark.parametrize("text, message", [
    ('{"a": 1, "b": 2, "a": 3}', r"^f\.json: file is not valid JSON \(key 'a' given twice in one object\)$"),
    ('[{"x": {"y": 1, "y": 1}}]', "key 'y' given twice in one object"),
    ('{"a": {"x": 1}, "b": {"x": 2}}', None),                          # the same key in two objects is fine
])
def test_json_reader_refuses_a_duplicate_key(text, message):
    """As YAML: json.loads would keep the last of a key given twice, silently."""
    from monorarp.core.readers import parse_json

    if message is None:
        assert parse_json(text, "f.json") == json.loads(text)
        return
    with pytest.raises(UserError, match=message):
        parse_json(text, "f.json")


def test_json_files_with_a_duplicate_key_are_refused(tmp_path, capsys):
    """Camera files and ``check`` baselines (both read by monorarp.core.readers.parse_json)."""
    from monorarp.core.camera import CameraError, CameraModel

    cam = tmp_path / "camera.json"
    cam.write_text('{"width": 640, "width": 320, "height": 360, "hfov_deg": 70, "height_m": 1.3}')
    with pytest.raises(CameraError, match=r"camera\.json: camera file is not valid JSON \(key 'width' given twice"):
        CameraModel.load(cam)
    results = _results_dir(tmp_path)
    baseline = tmp_path / "baseline.json"
    baseline.write_text(json.dumps(BASELINE)[:-1] + ', "version": 2}')
    rc, o, e = invoke(["check", str(results), "--baseline", str(baseline)], capsys)
    assert rc == 2 and o == "" and e.strip().splitlines() == [
        f"monorarp check: error: {baseline}: baseline is not valid JSON (key 'version' given twice in one object)"]


# ------------------------------------------------------------------------------ a real process
def test_real_process_stderr_is_one_line(base, tmp_path):
    """What the in-process tests cannot see: C-level output on file descriptor 2. A clip whose sample table
    box is renamed (one byte, found by the fuzzer) made OpenCV log two "[ERROR:0] ... Could not find decoder"
    lines before the error."""
    import subprocess
    import sys

    bad = tmp_path / "nostbl.mp4"
    bad.write_bytes((base / "clip.mp4").read_bytes().replace(b"stbl", b"\x0ftbl", 1))
    deep = tmp_path / "deep.yaml"
    deep.write_text("[" * 5000 + "]" * 5000)
    for argv in (["video", str(bad), "--camera", str(base / "camera.yaml"), "--out", str(tmp_path / "out")],
                 ["render", str(deep), "--out", str(tmp_path / "out")]):
        r = subprocess.run([sys.executable, "-m", "monorarp", *argv], capture_output=True, text=True, timeout=120)
        assert r.returncode == 2 and r.stdout == "", (r.returncode, r.stdout)
        assert len(r.stderr.splitlines()) == 1 and r.stderr.startswith(f"monorarp {argv[0]}: error: "), r.stderr
    assert not (tmp_path / "out").exists()
