"""Run the property-based fuzz tests with many examples and print how many cases each reader got.

    python benchmarks/fuzz_count.py                   # 10,000 examples per test, fresh random examples
    python benchmarks/fuzz_count.py --examples 500 --jobs 2
    python benchmarks/fuzz_count.py --only inputs     # or: estimators
    python benchmarks/fuzz_count.py -k check_ -k video_file   # only tests whose name holds one of these

Every test of ``tests/test_fuzz_inputs.py`` and ``tests/test_fuzz_estimators.py`` runs in its
own pytest process (``--jobs`` at a time) with ``MONORARP_FUZZ_EXAMPLES`` examples and
``MONORARP_FUZZ_RANDOM=1`` (not the derandomized CI examples). The counters are the
malformed documents each reader was actually given (generated documents that happened to be
valid are skipped before the command runs and not counted) and the frames / scenes the
estimators were fed. A failing test prints hypothesis' minimal example; exit status 1 then.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FILES = {"inputs": "tests/test_fuzz_inputs.py", "estimators": "tests/test_fuzz_estimators.py"}


def collect(files: list[str]) -> list[str]:
    out = subprocess.run([sys.executable, "-m", "pytest", "-q", "--collect-only", "-p", "no:cacheprovider", *files],
                         cwd=ROOT, capture_output=True, text=True, check=True).stdout
    ids = [line.split("[")[0] for line in out.splitlines() if "::test_" in line]
    return list(dict.fromkeys(ids))     # parametrized cases run together


def run_one(node: str, examples: int, tmp: Path) -> dict:
    counts = tmp / (node.replace("/", "_").replace(":", "_") + ".json")
    env = {**os.environ, "MONORARP_FUZZ_EXAMPLES": str(examples), "MONORARP_FUZZ_RANDOM": "1",
           "MONORARP_FUZZ_COUNTS": str(counts), "PYOPENGL_PLATFORM": os.environ.get("PYOPENGL_PLATFORM", "egl")}
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-x", "-p", "no:cacheprovider", node],
                          cwd=ROOT, env=env, capture_output=True, text=True)
    log = None
    if proc.returncode != 0:   # the whole report (hypothesis' example can be long), kept after the run
        log = Path(tempfile.gettempdir()) / f"fuzz_count-{node.split('::')[-1]}.log"
        log.write_text(proc.stdout + proc.stderr)
    return {"node": node, "rc": proc.returncode, "seconds": time.perf_counter() - t0,
            "counts": json.loads(counts.read_text()) if counts.exists() else {},
            "tail": "\n".join(line for line in (proc.stdout + proc.stderr).splitlines()
                              if line.startswith(("E ", "    | E", "FAILED")))[-6000:], "log": log}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--examples", type=int, default=10_000, help="hypothesis examples per test (default 10000)")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="tests run at once (default: cores)")
    ap.add_argument("--only", choices=sorted(FILES), default=None, help="one of the two test files")
    ap.add_argument("-k", action="append", default=None,
                    help="only tests whose name contains this (repeat: any of these)")
    args = ap.parse_args(argv)
    files = [FILES[args.only]] if args.only else list(FILES.values())
    nodes = [n for n in collect(files) if args.k is None or any(k in n for k in args.k)]
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp, ThreadPoolExecutor(args.jobs) as pool:
        results = list(pool.map(lambda n: run_one(n, args.examples, Path(tmp)), nodes))
    total: dict[str, int] = {}
    print(f"{'test':<62} {'status':>6} {'seconds':>8}")
    for r in results:
        for k, v in r["counts"].items():   # each process counts only what its own test fed
            total[k] = total.get(k, 0) + v
        print(f"{r['node']:<62} {'ok' if r['rc'] == 0 else 'FAIL':>6} {r['seconds']:8.1f}")
    print(f"\ncases tried ({args.examples} examples per test, random seeds, {time.perf_counter() - t0:.0f} s wall, "
          f"{args.jobs} job(s)):")
    for k, v in sorted(total.items()):
        print(f"  {k:<28} {v:>9,}")
    failed = [r for r in results if r["rc"] != 0]
    for r in failed:
        print(f"\n===== {r['node']} failed (full report: {r['log']}) =====\n{r['tail']}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
