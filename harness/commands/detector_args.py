"""The detector options shared by ``monorarp run`` and ``monorarp bench``."""

from __future__ import annotations

import argparse
from pathlib import Path

from monorarp.errors import UserError
from monorarp.pipeline import ComponentConfig

DEFAULT_DETECTOR = "centernet"


def add_detector_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--detector", default=DEFAULT_DETECTOR, metavar="NAME|PATH.onnx|oracle",
                   help="registered detector name, an ONNX model file, or 'oracle' (ground-truth boxes); "
                        f"default: {DEFAULT_DETECTOR}")
    p.add_argument("--refine-bottom", choices=("on", "off"), default=None,
                   help="CenterNet: sub-pixel bottom-edge refinement from the image (default: the detector's)")
    p.add_argument("--oracle-jitter", type=float, default=None, metavar="PX",
                   help="oracle: Gaussian std (px) added to each box edge (default 0)")
    p.add_argument("--oracle-miss-rate", type=float, default=None, metavar="R",
                   help="oracle: probability of dropping each object (default 0)")
    p.add_argument("--oracle-fp-rate", type=float, default=None, metavar="R",
                   help="oracle: mean number of false boxes per frame (Poisson; default 0)")


def detector_config(args: argparse.Namespace) -> ComponentConfig:
    """The detector the options describe; oracle noise options without ``--detector oracle`` are refused."""
    kw = {k: v for k, v in (("jitter_px", args.oracle_jitter), ("miss_rate", args.oracle_miss_rate),
                                   ("false_positives", args.oracle_fp_rate)) if v is not None}
    if kw and args.detector != "oracle":
        raise UserError("--oracle-jitter/--oracle-miss-rate/--oracle-fp-rate need --detector oracle")
    detector = args.detector
    refine = getattr(args, "refine_bottom", None)
    if refine is not None:
        if detector == "oracle" or (detector != "centernet" and not detector.lower().endswith(".onnx")):
            raise UserError(f"--refine-bottom applies to the CenterNet detector, not {detector!r}")
        kw["refine_bottom"] = refine == "on"
    if detector.lower().endswith(".onnx"):
        detector = str(Path(detector).expanduser())
    return ComponentConfig(name=detector, kwargs=kw)
