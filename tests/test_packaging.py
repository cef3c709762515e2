"""The pure pipeline installs and runs without the simulation harness's dependencies.

Two checks. Static: the base dependencies of ``pyproject.toml`` are exactly the
distributions whose modules ``monorarp/`` imports (at module level or lazily), and
every third-party module ``harness/`` imports is in the base or the ``harness``
extra. Dynamic: in a subprocess whose import system refuses every module of the
``harness`` and ``ray`` extras, ``monorarp --help`` lists every command,
``monorarp video`` runs on a small clip, and a harness command prints one line
naming the extra and exits 2.
"""

from __future__ import annotations

import ast
import json
import re
import subprocess
import sys
import tomllib
from importlib.metadata import packages_distributions
from pathlib import Path

import cv2
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
PROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
EXTRAS = PROJECT["optional-dependencies"]
# imported by harness/ only when installed (a probe of a Ray cluster; grpcio comes with ray[default])
OPTIONAL_MODULES = {"grpc"}


def _norm(requirement: str) -> str:
    """Distribution name of a requirement string, normalised as in PEP 503."""
    name = re.match(r"[A-Za-z0-9._-]+", requirement.strip()).group(0)
    return re.sub(r"[-_.]+", "-", name).lower()


def _dists(requirements: list[str]) -> set[str]:
    """Distributions named by ``requirements``, less the project itself (``monorarp[harness]``)."""
    return {_norm(r) for r in requirements} - {PROJECT["name"]}


def _third_party_imports(package: str) -> dict[str, str]:
    """Top-level third-party modules imported anywhere in ``package`` -> one place that imports it."""
    found: dict[str, str] = {}
    for path in sorted((ROOT / package).rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            for name in names:
                top = name.split(".")[0]
                if top not in sys.stdlib_module_names and top not in ("monorarp", "harness"):
                    found.setdefault(top, f"{path.relative_to(ROOT)}:{node.lineno}")
    return found


def _module_dists(module: str, where: str) -> set[str]:
    dists = packages_distributions().get(module)
    assert dists, f"{where} imports {module!r}, which no installed distribution provides"
    return {_norm(d) for d in dists}


def test_base_dependencies_are_what_the_pipeline_imports():
    base = _dists(PROJECT["dependencies"])
    imported: set[str] = set()
    for module, where in _third_party_imports("monorarp").items():
        dists = _module_dists(module, where)
        assert dists & base, f"{where} imports {module!r} ({', '.join(sorted(dists))}): not a base dependency"
        imported |= dists & base
    assert base <= imported, f"base dependencies monorarp/ never imports: {sorted(base - imported)}"


def test_harness_imports_are_in_the_base_or_the_harness_extra():
    allowed = _dists(PROJECT["dependencies"]) | _dists(EXTRAS["harness"]) | _dists(EXTRAS["ray"])
    for module, where in _third_party_imports("harness").items():
        if module in OPTIONAL_MODULES:
            continue
        if not packages_distributions().get(module) and _norm(module) in _dists(EXTRAS["ray"]):
            continue   # the ray extra, not installed here (`pip install -e ".[test]"`): its module is its name
        dists = _module_dists(module, where)
        assert dists & allowed, f"{where} imports {module!r} ({', '.join(sorted(dists))}): in no extra"
    harness = _dists(EXTRAS["harness"])
    assert not harness & _dists(PROJECT["dependencies"])
    for extra in ("test", "train", "ray"):   # each one runs the harness
        assert "monorarp[harness]" in EXTRAS[extra], f"the {extra!r} extra does not pull the harness extra"


# -- without the extra ---------------------------------------------------------------------------

def _blocked_modules() -> set[str]:
    """Top-level modules of the distributions of the harness and ray extras (as installed here)."""
    dists = _dists(EXTRAS["harness"]) | _dists(EXTRAS["ray"])
    blocked = {m for m, ds in packages_distributions().items() if {_norm(d) for d in ds} & dists}
    assert {"highway_env", "pyrender", "motmetrics"} <= blocked
    return blocked


RUNNER = """
import runpy, sys
BLOCKED = set(sys.argv[1].split(","))

class Refuse:
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in BLOCKED:
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)

sys.meta_path.insert(0, Refuse())
sys.argv = ["monorarp", *sys.argv[2:]]
runpy.run_module("monorarp", run_name="__main__", alter_sys=True)
"""


def _pure(tmp_path: Path, *args: str) -> subprocess.CompletedProcess:
    """``python -m monorarp ARGS`` with every module of the harness extra unimportable."""
    return subprocess.run([sys.executable, "-c", RUNNER, ",".join(sorted(_blocked_modules())), *args],
                          capture_output=True, text=True, cwd=ROOT, timeout=300)


def test_help_lists_every_command_without_the_extra(tmp_path):
    out = _pure(tmp_path, "--help")
    assert out.returncode == 0, out.stderr
    listed = set(re.findall(r"^    (\S+)", out.stdout, flags=re.M))
    assert listed == set(PROJECT["entry-points"]["monorarp.commands"])


@pytest.mark.parametrize("args", [
    ["run", "scenarios/highway_cruise.yaml", "--frames", "2"],           # fails when it runs
    ["bench", "trackers", "--frames", "2"],                              # fails while it registers
    ["sweep", "scenarios/ci.yaml"],
])
def test_harness_command_without_the_extra_says_what_to_install(tmp_path, args):
    out = _pure(tmp_path, *args, "--out", str(tmp_path / "out"))
    assert out.returncode == 2
    assert out.stdout == ""
    line = out.stderr.strip()
    assert "\n" not in line and "Traceback" not in line, out.stderr
    m = re.fullmatch(rf"monorarp {args[0]}: needs the simulation harness: "
                     r"pip install 'monorarp\[harness\]' \(missing: (\w+)\)", line)
    assert m and m.group(1) in _blocked_modules(), line
    assert not (tmp_path / "out").exists()


def test_video_runs_without_the_extra(tmp_path):
    width, height, fps = 320, 180, 10.0
    clip = tmp_path / "clip.mp4"
    writer = cv2.VideoWriter(str(clip), cv2.VideoWriter_fourcc(*"mp4v"), fps, (width, height))
    for i in range(4):   # sky, road, and a dark box drifting down: a vehicle coming closer
        frame = np.full((height, width, 3), 170, np.uint8)
        frame[height // 2:] = 90
        cv2.rectangle(frame, (140, 95 + i), (180, 120 + 2 * i), (30, 30, 30), -1)
        writer.write(frame)
    writer.release()
    camera = tmp_path / "camera.json"
    f = 228.5
    camera.write_text(json.dumps({"width": width, "height": height, "fx": f, "fy": f, "cx": 159.5, "cy": 89.5,
                                  "height_m": 1.3, "pitch_rad": 0.0}))
    out = _pure(tmp_path, "video", str(clip), "--camera", str(camera), "--out", str(tmp_path / "video"))
    assert out.returncode == 0, out.stderr
    records = (tmp_path / "video" / "predictions.jsonl").read_text().splitlines()
    assert len(records) == 4
    assert (tmp_path / "video" / "annotated.mp4").stat().st_size > 0
    assert json.loads((tmp_path / "video" / "run.json").read_text())
