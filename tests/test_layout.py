"""The tree is the architecture: the import contracts hold, no module reaches for another's private
name, and docs/architecture.md's tree is the package layout (docs/architecture.md#what-is-where)."""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("monorarp", "harness")
#: At most this many modules directly in monorarp/ (issue 41): the entry points and the public re-exports.
MAX_ROOT_MODULES = 8


def project_modules() -> list[Path]:
    return sorted(p.relative_to(ROOT) for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py")
                  if "__pycache__" not in p.parts)


def test_import_contracts_hold():
    """`lint-imports` with the contracts of pyproject.toml: no cycle (module-level or in a function),
    layers import only downwards, the pipeline never imports the harness or the simulator."""
    pytest.importorskip("importlinter")
    out = subprocess.run([sys.executable, "-c", "import sys; from importlinter.cli import lint_imports; "
                          "sys.exit(lint_imports(no_cache=True, no_logo=True))"],
                         cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stdout[-4000:] + out.stderr[-2000:]
    assert "broken" not in out.stdout.split("Contracts:")[-1].split(",")[0]


def test_a_broken_contract_is_caught(tmp_path):
    """The contracts can fail: the same configuration with a reversed layer order is broken."""
    pytest.importorskip("importlinter")
    cfg = tmp_path / "reversed.toml"
    cfg.write_text('[tool.importlinter]\nroot_packages = ["monorarp"]\n\n[[tool.importlinter.contracts]]\n'
                   'name = "core above app"\ntype = "layers"\nlayers = ["monorarp.core", "monorarp.app"]\n')
    out = subprocess.run([sys.executable, "-c", "import sys; from importlinter.cli import lint_imports; "
                          f"sys.exit(lint_imports(config_filename={str(cfg)!r}, no_cache=True, no_logo=True))"],
                         cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert out.returncode != 0 and "BROKEN" in out.stdout


def private_imports(source: str, where: str) -> list[str]:
    """``from <project module> import _name`` statements of ``source`` (dunder names are not private)."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] in PACKAGES:
            found += [f"{where}:{node.lineno}: from {node.module} import {a.name}" for a in node.names
                      if a.name.startswith("_") and not a.name.startswith("__")]
    return found


def test_no_module_imports_a_private_name():
    bad = [hit for p in project_modules() for hit in private_imports((ROOT / p).read_text(), str(p))]
    assert not bad, "\n".join(bad)


def test_the_private_name_check_sees_one():
    src = "from monorarp.core.types import _x\nfrom monorarp.core import __version__\nfrom numpy import _y\n"
    assert private_imports(src, "m.py") == ["m.py:1: from monorarp.core.types import _x"]


def test_few_modules_at_the_root_of_the_pipeline():
    root = sorted(p.name for p in (ROOT / "monorarp").glob("*.py"))
    assert len(root) <= MAX_ROOT_MODULES, root


# ------------------------------------------------------------------ docs/architecture.md's tree
NAME = re.compile(r"^(?:[\w.-]+\.py|[\w.-]+/)$")


def documented_tree(text: str) -> set[str]:
    """Paths named by the first code block after '## What is where': each line's leading names
    (``pkg/`` or ``mod.py``, several per line allowed, comma- or space-separated) nested by their
    indentation (two spaces a level); the rest of a line is its description."""
    block = text.split("## What is where", 1)[1].split("```", 2)[1]
    paths: set[str] = set()
    stack: list[str] = []
    for line in block.splitlines()[1:]:
        if not line.strip():
            continue
        level = (len(line) - len(line.lstrip(" "))) // 2
        names = []
        for tok in line.strip().replace(",", " ").split():
            if not NAME.match(tok):
                break
            names.append(tok)
        if not names:
            continue
        stack = stack[:level]
        parent = "".join(stack)
        for n in names:
            paths.add(parent + n)
        if names[-1].endswith("/"):
            stack.append(names[-1])
    return paths


def actual_tree() -> set[str]:
    """Every package (``dir/``) and module (but ``__init__.py``) of monorarp/ and harness/."""
    out: set[str] = set()
    for p in project_modules():
        if p.name != "__init__.py":
            out.add(p.as_posix())
        for parent in p.parents:
            if parent != Path("."):
                out.add(parent.as_posix() + "/")
    return out


def test_architecture_tree_is_the_package_layout():
    doc = documented_tree((ROOT / "docs" / "architecture.md").read_text())
    actual = actual_tree()
    doc_code = {p for p in doc if p.split("/")[0] in PACKAGES and not p.endswith("__init__.py")}
    data_dirs = {p for p in doc_code if p.endswith("/") and (ROOT / p).is_dir() and not any((ROOT / p).rglob("*.py"))}
    missing, stale = sorted(actual - doc_code), sorted(doc_code - actual - data_dirs)
    assert not missing and not stale, f"not in docs/architecture.md: {missing}\nin the doc, not in the tree: {stale}"


def test_tree_parser_nests_by_indentation():
    text = ("## What is where\n\n```\nmonorarp/     the pipeline\n  core/       shared\n    types.py, camera.py  records"
            "\n  cli.py      the CLI mentions x.py\nharness/\n```\n")
    assert documented_tree(text) == {"monorarp/", "monorarp/core/", "monorarp/core/types.py",
                                     "monorarp/core/camera.py", "monorarp/cli.py", "harness/"}
