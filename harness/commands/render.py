"""``monorarp render`` (placeholder until the renderer lands)."""


def register(sub) -> None:
    p = sub.add_parser("render", help="simulate and render a scenario to frames + ground truth")
    p.set_defaults(func=lambda a: 0)
