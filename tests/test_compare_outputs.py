"""scripts/compare_outputs.py: equal trees compare equal; a changed value, row, line or frame is found."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
from compare_outputs import compare, main  # noqa: E402


def _tree(root: Path) -> Path:
    (root / "run").mkdir(parents=True)
    (root / "run" / "metrics.json").write_text(json.dumps(
        {"distance": {"rel_err_median": 0.01}, "fps": 80.0, "timings_ms": {"tracker": 1.0}, "x": float("nan")}))
    (root / "run" / "per_frame.csv").write_text("frame,risk\n0,0.5\n1,0.25\n")
    (root / "run" / "ground_truth.jsonl").write_text('{"frame": 0, "t": 0.0}\n')
    (root / "run" / "frames.mp4").write_bytes(b"\x00\x01\x02")
    (root / "run.txt").write_text(f"wrote {root}/run/\nprocessed 40 frames in 1.2 s\nMOTA 1.000\n")
    return root


def test_equal_trees_differ_only_in_timings_and_paths(tmp_path, capsys):
    ref, new = _tree(tmp_path / "a"), _tree(tmp_path / "b")
    metrics = json.loads((new / "run" / "metrics.json").read_text())
    metrics["fps"], metrics["timings_ms"]["tracker"] = 60.0, 3.0          # timings are not outputs
    (new / "run" / "metrics.json").write_text(json.dumps(metrics))
    (new / "run.txt").write_text(f"wrote {new}/run/\nprocessed 40 frames in 2.7 s\nMOTA 1.000\n")
    assert compare(ref, new) == 0
    assert "0 differing" in capsys.readouterr().out


def test_every_kind_of_change_is_found(tmp_path, capsys):
    ref = _tree(tmp_path / "a")
    for name, change in [("run/metrics.json", lambda p: p.write_text(p.read_text().replace("0.01", "0.02"))),
                         ("run/per_frame.csv", lambda p: p.write_text(p.read_text().replace("0.25", "0.26"))),
                         ("run/ground_truth.jsonl", lambda p: p.write_text('{"frame": 0, "t": 0.1}\n')),
                         ("run/frames.mp4", lambda p: p.write_bytes(b"\x00\x01\x03")),
                         ("run.txt", lambda p: p.write_text(p.read_text().replace("MOTA 1.000", "MOTA 0.990"))),
                         ("run/extra.json", lambda p: p.write_text("{}"))]:
        new = tmp_path / "b"
        shutil.rmtree(new, ignore_errors=True)
        shutil.copytree(ref, new)
        change(new / name)
        assert compare(ref, new) == 1, name
        assert name.split("/")[-1] in capsys.readouterr().out


def test_missing_or_empty_snapshot_is_refused_not_passed(tmp_path, capsys):
    ref = _tree(tmp_path / "a")
    (tmp_path / "empty").mkdir()
    assert main([str(ref), str(tmp_path / "nope")]) == 2
    assert main([str(tmp_path / "empty"), str(ref)]) == 2
    assert main([str(ref)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 3 and "nope" in err[0] and "empty" in err[1] and err[2].startswith("usage:")
    assert main([str(ref), str(ref)]) == 0
