"""The documentation against the code: every ``monorarp`` command line written in README.md and
docs/*.md names a real sub-command and only options its parser has (checked on the argparse
parser, without running anything); every option of a ``python benchmarks/...`` / ``scripts/...``
command exists in that script; every relative link points to an existing file and heading.
"""

from __future__ import annotations

import argparse
import re
import unicodedata
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]

FENCE = re.compile(r"^\s*```")
INLINE_CODE = re.compile(r"`([^`\n]+)`")
LONG_OPTION = re.compile(r"(?<![\w-])--[a-z][a-z0-9-]*")
LINK = re.compile(r"(?<!!)\[[^\]\n]*\]\(([^)\s]+)\)")


# ------------------------------------------------------------------------------ reading the pages
def _code_blocks(text: str) -> list[list[str]]:
    """Lines of each fenced code block."""
    blocks, current = [], None
    for line in text.splitlines():
        if FENCE.match(line):
            if current is None:
                current = []
            else:
                blocks.append(current)
                current = None
        elif current is not None:
            current.append(line)
    return blocks


def _prose(text: str) -> str:
    """The text outside fenced code blocks."""
    out, inside = [], False
    for line in text.splitlines():
        if FENCE.match(line):
            inside = not inside
        elif not inside:
            out.append(line)
    return "\n".join(out)


def _strip_comment(line: str) -> str:
    """Drop a shell comment (`` # ...`` outside quotes)."""
    m = re.search(r"(^|\s)#", line)
    return line[: m.start()] if m else line


def _block_commands(block: list[str]) -> list[str]:
    """Command lines of a code block: continuation lines (a trailing backslash, or an indented line
    that starts with ``[`` or ``--`` as in a synopsis) are joined to their command."""
    commands: list[str] = []
    joining = False
    for raw in block:
        line = _strip_comment(raw).rstrip()
        stripped = line.strip()
        if not stripped:
            joining = False
            continue
        cont = joining or (commands and raw[:1].isspace() and stripped[:1] in "[-")
        if cont and commands:
            commands[-1] += " " + stripped.rstrip("\\")
        else:
            commands.append(stripped.rstrip("\\"))
        joining = line.endswith("\\")
    return commands


def _split_chain(command: str) -> list[str]:
    """Split ``a && b``, ``a | b``, ``a; b`` (a ``|`` inside a word, as in ``NAME|PATH.onnx``, stays)."""
    return [c.strip() for c in re.split(r"\s+(?:&&|\|\||\|)\s+|;\s+", command) if c.strip()]


def documented_commands() -> list[tuple[str, str]]:
    """(page, command) for every command line in a code block or an inline code span."""
    found = []
    for page in PAGES:
        text = page.read_text(encoding="utf-8")
        for block in _code_blocks(text):
            for cmd in _block_commands(block):
                found.extend((page.name, c) for c in _split_chain(cmd))
        for span in INLINE_CODE.findall(_prose(text)):
            found.extend((page.name, c) for c in _split_chain(span))
    return found


def _monorarp_words(command: str) -> list[str] | None:
    """The words after ``monorarp`` (or ``python -m monorarp``), or None for another command."""
    words = command.split()
    for i, w in enumerate(words):
        if w == "monorarp" and (i == 0 or words[i - 1] == "-m"):
            return words[i + 1:]
    return None


# ------------------------------------------------------------------------------ the parsers
def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def _options(parser: argparse.ArgumentParser) -> set[str]:
    return {o for a in parser._actions for o in a.option_strings if o.startswith("--")}


@pytest.fixture(scope="module")
def cli() -> argparse.ArgumentParser:
    from monorarp.app.cli import build_parser

    return build_parser()


def _resolve(cli: argparse.ArgumentParser, words: list[str]) -> tuple[str, argparse.ArgumentParser] | None:
    """(sub-command path, its parser) for ``words``; None when the first word is no command."""
    subs = _subparsers(cli)
    if not words or words[0] not in subs:
        return None
    name, parser = words[0], subs[words[0]]
    nested = _subparsers(parser)
    if nested and len(words) > 1 and words[1] in nested:
        name, parser = f"{name} {words[1]}", nested[words[1]]
    return name, parser


# ------------------------------------------------------------------------------ the tests
def test_pages_exist():
    assert (ROOT / "docs" / "README.md").is_file() and len(PAGES) >= 10


def test_commands_found():
    """The extraction sees the documented commands (a parser that finds nothing checks nothing)."""
    cmds = [c for _, c in documented_commands() if _monorarp_words(c) is not None]
    names = {w[0] for c in cmds if (w := _monorarp_words(c))}
    assert {"run", "render", "export", "sweep", "check", "scorecard", "bench", "video", "calibrate-horizon"} <= names
    assert len(cmds) >= 40


def test_documented_commands_and_options_exist(cli):
    problems = []
    for page, command in documented_commands():
        words = _monorarp_words(command)
        if words is None or not words or words[0].startswith("-"):
            continue
        if words[0] == "COMMAND" or words[0].endswith(":"):  # "monorarp COMMAND --help"; printed "monorarp run: error: ..."
            continue
        resolved = _resolve(cli, words)
        if resolved is None:
            problems.append(f"{page}: `monorarp {words[0]}` is no sub-command: {command}")
            continue
        name, parser = resolved
        known = _options(parser) | {"--help"}
        for opt in LONG_OPTION.findall(" ".join(words)):
            if opt not in known:
                problems.append(f"{page}: `monorarp {name}` has no option {opt}: {command}")
    assert not problems, "\n".join(problems)


def _script_options(path: Path) -> set[str]:
    return set(re.findall(r"""["'](--[a-z][a-z0-9-]*)["']""", path.read_text(encoding="utf-8")))


def test_script_options_exist():
    """``python benchmarks/x.py --opt`` / ``python -m training.reproduce --opt``: the script has the option."""
    problems, seen = [], 0
    for page, command in documented_commands():
        m = re.match(r"python3? (?:(?P<path>(?:benchmarks|scripts)/\w+\.py)|-m (?P<mod>training\.\w+))(?P<rest>.*)", command)
        if not m:
            continue
        path = ROOT / (m["path"] or m["mod"].replace(".", "/") + ".py")
        if not path.is_file():
            problems.append(f"{page}: no such script {path.relative_to(ROOT)}: {command}")
            continue
        seen += 1
        for opt in LONG_OPTION.findall(m["rest"]):
            if opt not in _script_options(path):
                problems.append(f"{page}: {path.relative_to(ROOT)} has no option {opt}")
    assert seen >= 3 and not problems, "\n".join(problems)


def test_lone_options_exist(cli):
    """An option quoted on its own in prose (`--warning-threshold`) exists in some monorarp parser or script."""
    known = set()
    stack = [cli]
    while stack:
        p = stack.pop()
        known |= _options(p)
        stack.extend(_subparsers(p).values())
    for folder in ("benchmarks", "scripts", "training"):
        for path in (ROOT / folder).glob("*.py"):
            known |= _script_options(path)
    problems = []
    for page in PAGES:
        for span in INLINE_CODE.findall(_prose(page.read_text(encoding="utf-8"))):
            words = span.split()
            if words and words[0].startswith("--"):
                opt = LONG_OPTION.match(words[0])
                if opt and opt.group(0) not in known:
                    problems.append(f"{page.name}: unknown option {opt.group(0)}")
    assert not problems, "\n".join(problems)


def github_slug(heading: str) -> str:
    """GitHub's anchor for a heading: lower case, markup and punctuation dropped, spaces to hyphens."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading)  # links keep their text
    text = text.replace("`", "").strip().lower()
    text = "".join(ch for ch in text if ch in " -_" or unicodedata.category(ch)[0] in "LN")
    return text.replace(" ", "-")


def anchors(page: Path) -> set[str]:
    """The anchors of a page's headings (a repeated heading gets -1, -2, ... as on GitHub)."""
    seen: dict[str, int] = {}
    out = set()
    for line in _prose(page.read_text(encoding="utf-8")).splitlines():
        m = re.match(r"^#{1,6}\s+(.*?)\s*#*\s*$", line)
        if not m:
            continue
        slug = github_slug(m.group(1))
        n = seen.get(slug, 0)
        seen[slug] = n + 1
        out.add(slug if n == 0 else f"{slug}-{n}")
    return out


def test_github_slug_rules():
    assert github_slug("`monorarp run`: one scenario, scored end to end") == "monorarp-run-one-scenario-scored-end-to-end"
    assert github_slug("Sweep throughput (benchmarks/bench_sweep.py)") == "sweep-throughput-benchmarksbench_sweeppy"
    assert github_slug("Collision-warning scorecard (`scorecard.json`)") == "collision-warning-scorecard-scorecardjson"


def test_relative_links_resolve():
    problems, checked = [], 0
    for page in PAGES:
        for target in LINK.findall(_prose(page.read_text(encoding="utf-8"))):
            if re.match(r"^[a-z][a-z0-9+.-]*:", target):  # http:, https:, mailto:
                continue
            path_part, _, anchor = target.partition("#")
            dest = (page.parent / path_part).resolve() if path_part else page
            checked += 1
            if not dest.exists():
                problems.append(f"{page.name}: link to missing {target}")
                continue
            if anchor and dest.suffix == ".md" and anchor not in anchors(dest):
                problems.append(f"{page.name}: no heading #{anchor} in {dest.relative_to(ROOT)}")
    assert checked >= 50 and not problems, "\n".join(problems)


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_page_size(page):
    """Each page reads in one go: the start page within 10 KB, a reference page within 20 KB."""
    limit = 10_000 if page == ROOT / "README.md" else 20_000
    assert len(page.read_bytes()) <= limit


def test_repository_paths_exist():
    """A repository path quoted in the docs (`harness/scoring/hota.py`, `scenarios/fcw/`) exists."""
    tops = ("monorarp/", "harness/", "scenarios/", "benchmarks/", "scripts/", "training/", "tests/", "results/", ".ci/")
    problems, checked = [], 0
    for page in PAGES:
        text = page.read_text(encoding="utf-8")
        spans = INLINE_CODE.findall(_prose(text)) + [w for b in _code_blocks(text) for line in b for w in line.split()]
        for span in spans:
            path = span.strip().rstrip(",.;:)")
            if not path.startswith(tops) or not re.fullmatch(r"[\w./*-]+", path):
                continue
            checked += 1
            if not list(ROOT.glob(path)):
                problems.append(f"{page.name}: no {path}")
    assert checked >= 30 and not problems, "\n".join(sorted(set(problems)))


def test_every_registered_horizon_is_documented_with_the_option():
    """``monorarp run --help`` lists every registered horizon stage; cli.md's ``--horizon`` row names each."""
    from monorarp.pipeline.catalogue import BUILTINS

    row = next(line for line in (ROOT / "docs" / "cli.md").read_text(encoding="utf-8").splitlines()
               if line.startswith("| `--horizon` |"))
    missing = [name for name in BUILTINS["horizon"] if f"`{name}`" not in row]
    assert not missing, f"docs/cli.md --horizon row lacks {missing}"
