"""Compare two snapshots of ``scripts/outputs_snapshot.sh``: every value, timings aside.

    python scripts/compare_outputs.py REF_DIR NEW_DIR

JSON, JSONL and CSV files are compared value by value (keys naming a time, a rate or a path are
skipped: they differ run to run), text outputs line by line with numbers followed by a time unit
masked and the per-stage timing rows of Table II dropped, ``frames.mp4`` byte by byte; HTML reports
and the bench table (timings) are skipped. Prints each differing file with its first differences;
exit status 1 when anything differs. Two snapshots of the same code compare equal.
"""

from __future__ import annotations

import csv
import io
import json
import math
import re
import sys
from pathlib import Path
from typing import Any

VOLATILE_KEY = re.compile(r"(_ms$|^ms$|_ms_|fps|frames_per_s|wall|elapsed|seconds$|_time|^time$|started|finished|"
                          r"host|pid|^version|python|platform|cache|^out$|out_dir|^path$|_path$|^dir$|created|"
                          r"^mean$|^median$|^p90$|^p99$|^max$|^min$|^std$|runtime|throughput|^timings)")
TIMED_NUMBER = re.compile(r"\d+(\.\d+)?\s*(ms|s\b|frames/s|fps|x\b)")
STAGE_ROW = re.compile(r"^(Object Detector|Tracker|State Estimator|Risk Estimator|Ego Speed|Horizon|Warning|Total)")
SKIPPED = {".html"}
SKIPPED_NAMES = {"bench.txt", "trackers.md"}


def _text(s: str, roots: tuple[Path, Path]) -> str:
    for root in roots:
        s = s.replace(str(root), "<OUT>")
    return TIMED_NUMBER.sub("<T>", s)


def diff_values(a: Any, b: Any, path: str, out: list[str], roots: tuple[Path, Path]) -> None:
    """Append to ``out`` where ``a`` and ``b`` differ (volatile keys skipped; NaN equals NaN)."""
    if len(out) > 8:
        return
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b), key=str):
            if VOLATILE_KEY.search(str(k)) and not str(k).startswith("distance"):
                continue
            if k not in a or k not in b:
                out.append(f"{path}/{k}: only in {'new' if k not in a else 'ref'}")
            else:
                diff_values(a[k], b[k], f"{path}/{k}", out, roots)
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            out.append(f"{path}: {len(a)} items != {len(b)}")
        for i, (x, y) in enumerate(zip(a, b)):
            diff_values(x, y, f"{path}[{i}]", out, roots)
    elif isinstance(a, str) and isinstance(b, str):
        if _text(a, roots) != _text(b, roots):
            out.append(f"{path}: {a[:80]!r} != {b[:80]!r}")
    elif isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return
    elif a != b:
        out.append(f"{path}: {a!r} != {b!r}")


def diff_file(a: Path, b: Path, roots: tuple[Path, Path]) -> list[str] | None:
    """Differences between two files of the same name (None: a kind of file not compared)."""
    out: list[str] = []
    if a.suffix == ".json":
        diff_values(json.loads(a.read_text()), json.loads(b.read_text()), "", out, roots)
    elif a.suffix == ".jsonl":
        rows = [[json.loads(line) for line in p.read_text().splitlines() if line.strip()] for p in (a, b)]
        diff_values(rows[0], rows[1], "", out, roots)
    elif a.suffix == ".csv":
        rows = [list(csv.DictReader(io.StringIO(p.read_text()))) for p in (a, b)]
        diff_values(rows[0], rows[1], "", out, roots)
    elif a.suffix in (".txt", ".md") and a.name not in SKIPPED_NAMES:
        la, lb = ([_text(x, roots) for x in p.read_text(errors="replace").splitlines() if not STAGE_ROW.match(x)]
                  for p in (a, b))
        out += [f"line {i + 1}: {x[:100]!r} != {y[:100]!r}" for i, (x, y) in enumerate(zip(la, lb)) if x != y][:6]
        if len(la) != len(lb):
            out.append(f"{len(la)} lines != {len(lb)}")
    elif a.name == "frames.mp4":
        if a.read_bytes() != b.read_bytes():
            out.append("bytes differ")
    else:
        return None
    return out


def compare(ref: Path, new: Path) -> int:
    """Print the differences between two snapshot trees; the number of differing files."""
    ref, new = ref.resolve(), new.resolve()
    files = [{p.relative_to(root) for p in root.rglob("*") if p.is_file() and ".cache" not in p.parts
              and p.suffix not in SKIPPED} for root in (ref, new)]
    bad = 0
    for rel in sorted(files[0] ^ files[1]):
        print(f"only in {'ref' if rel in files[0] else 'new'}: {rel}")
        bad += 1
    for rel in sorted(files[0] & files[1]):
        diffs = diff_file(ref / rel, new / rel, (ref, new))
        if diffs:
            bad += 1
            print(f"differs: {rel}")
            for d in diffs[:8]:
                print(f"    {d}")
    print(f"{len(files[0] & files[1])} files in both, {bad} differing")
    return bad


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print("usage: python scripts/compare_outputs.py REF_DIR NEW_DIR", file=sys.stderr)
        return 2
    for d in argv:
        if not Path(d).is_dir() or not any(Path(d).iterdir()):
            print(f"compare_outputs: {d}: not a snapshot directory (missing or empty)", file=sys.stderr)
            return 2
    return 1 if compare(Path(argv[0]), Path(argv[1])) else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
