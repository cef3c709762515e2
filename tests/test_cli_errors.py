"""``monorarp``'s own argument errors: one line naming the sub-command, exit 2 (argparse prints a usage block)."""

from __future__ import annotations

import pytest

from monorarp.app.cli import main


@pytest.mark.parametrize("argv, line", [
    (["run", "x.yaml", "--frames", "abc"],
     "monorarp run: error: argument --frames: invalid int value: 'abc' (see monorarp run --help)"),
    (["run"], "monorarp run: error: the following arguments are required: SCENARIO.yaml (see monorarp run --help)"),
    (["scorecard", "--out", "x", "--bogus"],
     "monorarp scorecard: error: unrecognized arguments: --bogus (see monorarp scorecard --help)"),
    (["bench", "trackers", "--frames", "x"],
     "monorarp bench trackers: error: argument --frames: invalid int value: 'x' (see monorarp bench trackers --help)"),
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
