"""The pipeline package runs on real video: it must never pull in the harness or the simulator."""

import subprocess
import sys


def test_monorarp_never_imports_harness_simulator_or_renderer():
    code = """
import importlib, pkgutil, sys
import monorarp
for m in pkgutil.walk_packages(monorarp.__path__, "monorarp."):
    if m.name != "monorarp.__main__":
        importlib.import_module(m.name)
from monorarp.pipeline.registry import available, KINDS
for kind in KINDS:
    available(kind)
bad = sorted(n for n in sys.modules if n.split(".")[0] in ("harness", "highway_env", "pyrender", "gymnasium"))
print(",".join(bad))
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "", f"monorarp imported: {out.stdout.strip()}"
