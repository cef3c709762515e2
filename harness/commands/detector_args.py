"""The oracle detector's noise options (``monorarp run`` and ``monorarp bench``), added to the shared
pipeline options of :mod:`monorarp.app.options`."""

from __future__ import annotations

import argparse

from monorarp.core.errors import UserError
from monorarp.pipeline.config import ComponentConfig, PipelineConfig


def add_oracle_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--oracle-jitter", type=float, default=None, metavar="PX",
                   help="oracle: Gaussian std (px) added to each box edge (default 0)")
    p.add_argument("--oracle-miss-rate", type=float, default=None, metavar="R",
                   help="oracle: probability of dropping each object (default 0)")
    p.add_argument("--oracle-fp-rate", type=float, default=None, metavar="R",
                   help="oracle: mean number of false boxes per frame (Poisson; default 0)")


def with_oracle_noise(cfg: PipelineConfig, args: argparse.Namespace) -> PipelineConfig:
    """``cfg`` with the oracle noise options (where the command has them) in its detector's kwargs; refused
    without ``--detector oracle``."""
    kw = {k: v for k, v in (("jitter_px", getattr(args, "oracle_jitter", None)),
                            ("miss_rate", getattr(args, "oracle_miss_rate", None)),
                            ("false_positives", getattr(args, "oracle_fp_rate", None))) if v is not None}
    if not kw:
        return cfg
    if cfg.detector.name != "oracle":
        raise UserError("--oracle-jitter/--oracle-miss-rate/--oracle-fp-rate need --detector oracle")
    detector = ComponentConfig(name="oracle", kwargs={**kw, **cfg.detector.kwargs})
    return cfg.model_copy(update={"detector": detector})


def pipeline_config(args: argparse.Namespace, base: PipelineConfig | None = None) -> PipelineConfig:
    """:func:`monorarp.app.options.pipeline_config` with the oracle detector known and its noise options."""
    from monorarp.app.options import pipeline_config as shared

    return with_oracle_noise(shared(args, base), args)
