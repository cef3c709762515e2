"""What ``monorarp bench trackers`` runs when not told otherwise (kept apart so the CLI can show it cheaply)."""

from pathlib import Path

DEFAULT_TRACKERS = ("particle", "kcf", "csrt", "mosse", "medianflow", "sort", "bytetrack")
#: the shipped scenarios, named relative to the project root (where the scorecard's suites are found too:
#: from any directory); scenarios the user names are relative to the current directory
DEFAULT_SCENARIOS = ("scenarios/highway_cruise.yaml", "scenarios/cut_in.yaml")
PROJECT_ROOT = Path(__file__).resolve().parents[2]
DEFAULT_FRAMES = 90          # per scenario, capped at its duration x fps
#: ``--seeds``: at most this many seeds (a range of more is refused before anything runs)
MAX_SEEDS = 10_000


def default_scenarios() -> list[str]:
    """:data:`DEFAULT_SCENARIOS` as paths that hold from any current directory."""
    return [str(PROJECT_ROOT / s) for s in DEFAULT_SCENARIOS]
