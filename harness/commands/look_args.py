"""``--look``, ``--look-family`` and ``--look-seed``: a scenario's look set from the command line
(``render.look``, ``render.look_family``, ``render.look_seed``; :mod:`harness.render.look`)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from monorarp.app.common_options import int_in

if TYPE_CHECKING:
    from harness.world.scenario import Scenario


def add_look_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--look", choices=("simple", "realistic"), default=None,
                   help="the renders' look: simple (flat-shaded boxes, uniform sky) or realistic (textured road, "
                        "roadside, sky, sun shadows, sensor model; docs/looks.md); default: the scenario's render.look")
    p.add_argument("--look-family", choices=("train", "heldout"), default=None,
                   help="realistic look: the randomisation family (default: the scenario's, train)")
    p.add_argument("--look-seed", type=int_in(0, 2**32 - 1), default=None, metavar="N",
                   help="realistic look: the seed of its randomisation (default: the scenario's look_seed, "
                        "else its seed)")


def look_update(args: argparse.Namespace) -> dict:
    """The ``render`` fields the look options set (empty when none was given)."""
    return {k: v for k, v in (("look", args.look), ("look_family", args.look_family),
                              ("look_seed", args.look_seed)) if v is not None}


def apply_look(scenario: Scenario, args: argparse.Namespace) -> Scenario:
    """``scenario`` with the look options that were given (unchanged when none was)."""
    update = look_update(args)
    if not update:
        return scenario
    return scenario.model_copy(update={"render": scenario.render.model_copy(update=update)})
