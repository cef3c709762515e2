"""The benchmark scripts' shared pieces (harness.bench.targets, harness.bench.script) and their bad-input refusals."""

import subprocess
import sys
from pathlib import Path

import pytest

from harness.bench.script import run_script
from harness.bench.targets import target_table
from monorarp.core.errors import UserError

ROOT = Path(__file__).resolve().parents[1]


def test_target_table_aligns_required_and_measured_columns():
    text = target_table("title", [("a", ">= 0.95", "0.90"), ("longer target", "", "12 s")])
    lines = text.splitlines()
    assert lines[0] == "title"
    assert lines[1] == "  a              >= 0.95  0.90"
    assert lines[2] == "  longer target           12 s"
    assert target_table("only a title", []) == "only a title"


def test_run_script_turns_a_user_error_into_one_line_and_exit_2(capsys, monkeypatch):
    monkeypatch.setattr(sys, "argv", ["/x/bench_y.py"])

    def bad() -> None:
        raise UserError("scenarios/z.yaml: no such file")

    with pytest.raises(SystemExit) as e:
        run_script(bad)
    assert e.value.code == 2
    assert capsys.readouterr().err == "bench_y.py: error: scenarios/z.yaml: no such file\n"
    with pytest.raises(ZeroDivisionError):          # a bug is not a user error: its traceback stays
        run_script(lambda: 1 / 0)


@pytest.mark.parametrize("args, message", [
    (["bench_tracking.py", "--detector", "nosuch"], "unknown detector 'nosuch'"),
    (["bench_tracking.py", "--seeds", "5-3"], "--seeds"),
    (["bench_conditions.py", "--conditions", "bogus"], "--conditions: unknown bogus"),
    (["bench_eval_kitti.py", "--size", "12x"], "--size"),
    (["bench_eval_kitti.py", "--scenario", "/nonexistent/s.yaml", "--frames", "2"], "cannot read scenario"),
])
def test_benchmark_scripts_refuse_bad_input_in_one_line(tmp_path, args, message):
    out = subprocess.run([sys.executable, str(ROOT / "benchmarks" / args[0]), *args[1:]], cwd=tmp_path,
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 2
    assert message in out.stderr and "Traceback" not in out.stderr
    assert out.stderr.strip().splitlines()[-1].startswith(f"{args[0]}: error:")
    assert not any(tmp_path.iterdir())
