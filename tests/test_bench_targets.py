"""The benchmark scripts' target tables (harness.bench.targets)."""

from harness.bench.targets import target_table


def test_target_table_aligns_required_and_measured_columns():
    text = target_table("title", [("a", ">= 0.95", "0.90"), ("longer target", "", "12 s")])
    lines = text.splitlines()
    assert lines[0] == "title"
    assert lines[1] == "  a              >= 0.95  0.90"
    assert lines[2] == "  longer target           12 s"
    assert target_table("only a title", []) == "only a title"
