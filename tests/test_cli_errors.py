"""``monorarp``'s own argument errors: one line naming the sub-command, exit 2 (argparse prints a usage block)."""

from __future__ import annotations

import re

import pytest

from monorarp.app.cli import main


@pytest.mark.parametrize("argv, line", [
    (["run", "x.yaml", "--frames", "abc"],
     "monorarp run: error: argument --frames: must be a positive integer, got 'abc' (see monorarp run --help)"),
    (["run"], "monorarp run: error: the following arguments are required: SCENARIO.yaml (see monorarp run --help)"),
    (["scorecard", "--out", "x", "--bogus"],
     "monorarp scorecard: error: unrecognized arguments: --bogus (see monorarp scorecard --help)"),
    (["bench", "trackers", "--frames", "x"],
     "monorarp bench trackers: error: argument --frames: must be a positive integer, got 'x' "
     "(see monorarp bench trackers --help)"),
    (["--bogus"], "monorarp: error: unrecognized arguments: --bogus (see monorarp --help)"),
])
def test_argument_errors_are_one_line(argv, line, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    try:
        code = main(argv)            # an unknown option: returned
    except SystemExit as e:          # any other argument error: argparse exits
        code = e.code
    assert code == 2
    assert capsys.readouterr().err.splitlines() == [line]
    assert not list(tmp_path.iterdir())


def _refusal(argv: list[str], capsys) -> str:
    """The one error line of ``monorarp argv`` (exit 2), without the ``monorarp CMD: error:`` prefix and
    the ``(see ... --help)`` suffix that name the sub-command."""
    try:
        code = main(argv)
    except SystemExit as e:
        code = e.code
    lines = capsys.readouterr().err.splitlines()
    assert code == 2 and len(lines) == 1, (argv, code, lines)
    m = re.fullmatch(r"monorarp ([a-z -]+): error: (.*) \(see monorarp \1 --help\)", lines[0])
    assert m and m.group(1) == " ".join(argv[:2] if argv[0] in ("eval", "bench") else argv[:1]), (argv, lines)
    return m.group(2)


#: every command taking ``--frames`` / ``--out``, with the rest of a command line it accepts
FRAMES_COMMANDS = {
    "run": ["run", "s.yaml"], "render": ["render", "s.yaml", "--out", "o"],
    "export": ["export", "s.yaml", "--format", "kitti", "--out", "o"], "eval": ["eval", "kitti", "d", "--out", "o"],
    "scorecard": ["scorecard", "--out", "o"], "bench": ["bench", "trackers"],
    "video": ["video", "in.mp4", "--camera", "c.yaml"], "calibrate-horizon": ["calibrate-horizon", "in.mp4", "--camera", "c.yaml"],
}
OUT_COMMANDS = {
    "run": ["run", "s.yaml"], "render": ["render", "s.yaml"], "export": ["export", "s.yaml", "--format", "kitti"],
    "eval": ["eval", "kitti", "d"], "sweep": ["sweep", "spec.yaml"], "scorecard": ["scorecard"],
    "bench": ["bench", "trackers"], "video": ["video", "in.mp4", "--camera", "c.yaml"],
}


@pytest.mark.parametrize("value, refusal", [
    ("0", "argument --frames: must be a positive integer, got 0"),
    ("-1", "argument --frames: must be a positive integer, got -1"),
    ("abc", "argument --frames: must be a positive integer, got 'abc'"),
    ("1.5", "argument --frames: must be a positive integer, got '1.5'"),
])
def test_frames_refused_in_the_same_words_by_every_command(value, refusal, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for name, argv in FRAMES_COMMANDS.items():
        assert _refusal([*argv, "--frames", value], capsys) == refusal, name
    assert _refusal([*FRAMES_COMMANDS["video"], "--max-frames", value], capsys) == \
        refusal.replace("--frames", "--max-frames")          # the old name, still accepted
    assert not list(tmp_path.iterdir())


def test_empty_out_refused_in_the_same_words_by_every_command(capsys, tmp_path, monkeypatch):
    """``--out ''`` would be the current directory (a render there replaced it): refused, nothing written."""
    monkeypatch.chdir(tmp_path)
    for name, argv in OUT_COMMANDS.items():
        assert _refusal([*argv, "--out", ""], capsys) == "argument --out: must name a directory, got ''", name
    assert not list(tmp_path.iterdir())


def test_camera_and_workers_refused_in_the_same_words(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for command in ("video", "calibrate-horizon"):
        assert _refusal([command, "in.mp4", "--camera", ""], capsys) == \
            "argument --camera: must name a camera file, got ''"
    for argv in (["sweep", "spec.yaml", "--out", "o"], ["scorecard", "--out", "o"]):
        assert _refusal([*argv, "--workers", "0"], capsys) == "argument --workers: must be a positive integer, got 0"
    assert not list(tmp_path.iterdir())


def test_video_takes_frames_and_its_old_name_hidden(capsys):
    from monorarp.app.cli import build_parser

    parser = build_parser()
    base = ["video", "in.mp4", "--camera", "c.yaml"]
    assert parser.parse_args(base).frames is None
    assert parser.parse_args([*base, "--frames", "5"]).frames == 5
    assert parser.parse_args([*base, "--max-frames", "7"]).frames == 7
    assert parser.parse_args(["calibrate-horizon", "in.mp4", "--camera", "c.yaml"]).frames == 150
    with pytest.raises(SystemExit):
        parser.parse_args(["video", "--help"])
    shown = capsys.readouterr().out
    assert "--frames N" in shown and "--max-frames" not in shown


def test_library_checks_word_frames_as_the_parser_does(tmp_path):
    """The checks behind the commands (for callers of the library functions) say what the parser says."""
    from harness.export.source import ExportInputError, open_source
    from harness.world.scenario import Scenario, frames_to_simulate
    from monorarp.app.common_options import check_frames, frames_within
    from monorarp.core.errors import UserError

    scenario = Scenario(name="x")
    for call in (lambda: check_frames(0), lambda: frames_within(0, 5, "scenario's"),
                 lambda: frames_to_simulate(scenario, 0, "s.yaml"), lambda: open_source(tmp_path, 0)):
        with pytest.raises(UserError) as e:
            call()
        assert str(e.value) == "--frames: must be a positive integer, got 0"
    with pytest.raises(ExportInputError):
        open_source(tmp_path, -1)
    with pytest.raises(UserError, match=r"^--frames: 151 exceeds the scenario's 150 frames \(duration_s \* fps\); "
                                        r"raise duration_s in s.yaml to run more$"):
        frames_to_simulate(scenario, 151, "s.yaml", "run")
    assert frames_within(None, 8, "dataset's") == 8 and frames_within(3, 8, "dataset's") == 3
