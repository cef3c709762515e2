"""What ``monorarp bench trackers`` runs when not told otherwise (kept apart so the CLI can show it cheaply)."""

DEFAULT_TRACKERS = ("particle", "kcf", "csrt", "mosse", "medianflow", "sort", "bytetrack")
DEFAULT_SCENARIOS = ("scenarios/highway_cruise.yaml", "scenarios/cut_in.yaml")
DEFAULT_FRAMES = 90          # per scenario, capped at its duration x fps
