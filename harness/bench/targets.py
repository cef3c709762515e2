"""The target tables the benchmark scripts print: one (target, required, measured) row a line."""

from __future__ import annotations

from collections.abc import Sequence


def target_table(title: str, rows: Sequence[tuple[str, str, str]]) -> str:
    """``title``, then each row as aligned columns: target, what it requires, what was measured."""
    w = max((len(r[0]) for r in rows), default=0)
    r = max((len(r[1]) for r in rows), default=0)
    return "\n".join([title] + [f"  {target:<{w}}  {required:<{r}}  {got}" for target, required, got in rows])
