"""The command-line options that choose a pipeline's components, shared by every command that runs one.

:func:`add_pipeline_options` adds them to a parser (only the stages a command lets the user choose);
:func:`pipeline_config` turns the parsed options into a :class:`~monorarp.pipeline.config.PipelineConfig`,
checking every name against :mod:`monorarp.pipeline.registry` (built-ins and entry-point plug-ins alike). A stage
without options keeps :class:`PipelineConfig`'s default, which is where every default lives, except the
command-line defaults stated here because they differ from a bare config:

* ``--ego-speed`` defaults to :data:`CLI_EGO_SPEED` (a config without the option has no ego-speed stage);
* ``--velocity`` (the geometric state estimator's) is written into the config, default ``kalman``;
* ``--horizon calibrated`` (the default) means no horizon stage;
* ``--detector`` defaults to :data:`~monorarp.pipeline.config.REAL_WORLD_DETECTOR` where the frames are real
  (``video``: :data:`REAL_FRAMES`), to :class:`PipelineConfig`'s (``centernet``) where they are rendered;
* where the frames are real (:data:`REAL_FRAMES`) the state estimator gets
  :data:`~monorarp.state.config.REAL_FRAMES_STATE` (the size prior on, the box bottom at the rear face);
  ``--size-prior on|off`` sets ``size_prior`` alone; left out elsewhere, the config is as given;
* where the frames are real, a risk stage built on :class:`~monorarp.risk.estimators.TTCRiskEstimator`
  (``ttc``, ``manoeuvre``) gets :data:`REAL_FRAMES_RISK`: the TTC from the significant velocity;
* where the frames are real, a warning stage built on :class:`~monorarp.warning.fcw.ForwardCollisionWarning`
  (``fcw``) gets :data:`REAL_FRAMES_WARNING` under the config's own ``warning`` kwargs (which win): the rules
  re-checked on real tracks (docs/warning_real.md).

The TTC thresholds (the warning stage's alert, the paper's per-object cue) are defined once, in
:mod:`monorarp.warning.thresholds`. The other options several commands share (``--frames``, ``--out``,
``--camera``, ``--threaded``, ``--no-video``) are in :mod:`monorarp.app.common_options`.
"""

from __future__ import annotations

import argparse
from collections.abc import Iterable
from typing import Any

from monorarp.pipeline import registry
from monorarp.core.errors import UserError
from monorarp.pipeline.config import REAL_WORLD_DETECTOR, ComponentConfig, PipelineConfig, check_weak_detections
from monorarp.state.config import REAL_FRAMES_STATE

STAGES = ("detector", "tracker", "state", "risk", "ego_speed", "horizon")
CLI_EGO_SPEED = "ground_track"          # the run/video commands' ego-speed stage unless --ego-speed none
VELOCITIES = ("kalman", "difference")
DEFAULT_VELOCITY = "kalman"
CALIBRATED = "calibrated"               # --horizon: the calibration's horizon, no horizon stage
NONE = "none"                           # --ego-speed: no ego-speed stage
REAL_FRAMES = {"detector": REAL_WORLD_DETECTOR,   # the defaults of the commands whose frames are real (video)
               "size_prior": "on", "significant_velocity": "on", "warning_rules": "real"}
#: The TTC risk settings where frames are real: each velocity component counted beyond 2 of its one-sigmas
#: (floored by the distance's over the track's age: monorarp.risk.estimators.significant_velocity), the
#: 95 % bound (1.96 sigma) a real box's velocity must clear to be taken as motion (docs/pipeline.md).
REAL_FRAMES_RISK: dict[str, Any] = {"velocity_sigmas": 2.0}
#: The warning stage's settings where frames are real (docs/warning_real.md): no registered-patch veto. On the
#: real clip it blocked none of the tracks the other rules let near the threshold; on real footage with a
#: closing lead pasted in, the range filter restarts (label flips, box jumps) and over-reads the closing
#: speed, and the veto then dropped the due warning (1.67 -> 3.91 s before contact; 1.33 -> 2.80 s).
REAL_FRAMES_WARNING: dict[str, Any] = {"registered_share": None}


class _RegistryHelp(str):
    """A help text whose ``{names}`` becomes the registry's names of ``kind`` only when help is shown
    (argparse fills help texts with ``%``), so building a parser imports no component."""

    kind: str

    def __new__(cls, kind: str, text: str) -> "_RegistryHelp":
        obj = super().__new__(cls, text)
        obj.kind = kind
        return obj

    def __mod__(self, params: Any) -> str:
        return str.__mod__(str(self).replace("{names}", ", ".join(registry.available(self.kind))), params)


def default_name(kind: str) -> str:
    """The default component of ``kind`` on the command line."""
    if kind == "ego_speed":
        return CLI_EGO_SPEED
    return PipelineConfig.model_fields[kind].default.name


def add_pipeline_options(p: argparse.ArgumentParser, stages: Iterable[str] = STAGES,
                         defaults: dict[str, str] | None = None) -> None:
    """Add the options choosing ``stages`` (kinds of :data:`STAGES`) to ``p``.

    ``defaults`` (kind -> name) replaces a stage's default where a command documents another one.
    """
    stages = set(stages)
    unknown = stages - set(STAGES)
    if unknown:
        raise ValueError(f"no options for stages {sorted(unknown)}; options exist for {', '.join(STAGES)}")
    defaults = defaults or {}
    p.set_defaults(_pipeline_stages=tuple(k for k in STAGES if k in stages))   # read by pipeline_config
    p.set_defaults(_warning_defaults=REAL_FRAMES_WARNING if defaults.get("warning_rules") == "real" else {})

    def default(kind: str) -> str:
        return defaults.get(kind, default_name(kind))

    if "detector" in stages:
        p.add_argument("--detector", default=default("detector"), metavar="NAME|PATH.onnx",
                       help=_RegistryHelp("detector", "registered detector ({names}; 'yolo' ships no weights: it "
                                          "needs a YOLOv8/YOLO11 ONNX export given as PATH.onnx) or an ONNX model "
                                          f"file (CenterNet, YOLOX or YOLO layout); default: {default('detector')}"))
        p.add_argument("--refine-bottom", choices=("on", "off"), default=None,
                       help="CenterNet: sub-pixel bottom-edge refinement from the image (default: the detector's)")
        p.add_argument("--weak-detections", type=float, default=None, metavar="SCORE",
                       help="CenterNet: also give the tracker the boxes scoring from SCORE up to the detector's "
                            "threshold, as weak detections (they extend tracks, never start one; only for a tracker "
                            "that takes them, the particle one; default: off)")
    if "tracker" in stages:
        p.add_argument("--tracker", default=default("tracker"), metavar="NAME",
                       help=_RegistryHelp("tracker", f"registered tracker ({{names}}; default: {default('tracker')})"))
    if "state" in stages:
        p.add_argument("--velocity", choices=VELOCITIES, default=DEFAULT_VELOCITY,
                       help=f"relative velocity of the state estimator (default: {DEFAULT_VELOCITY})")
        size = defaults.get("size_prior")
        p.set_defaults(_state_defaults=REAL_FRAMES_STATE if size == "on" else {})   # read by pipeline_config
        p.add_argument("--size-prior", choices=("on", "off"), default=None,
                       help="fuse each vehicle's distance from its kind's height and width with the ground plane's "
                            f"(default: {size or 'the config, off'})")
    if "ego_speed" in stages:
        p.add_argument("--ego-speed", default=default("ego_speed"), metavar="NAME|none",
                       help=_RegistryHelp("ego_speed", "lane-marking ego-speed estimator ({names}), or none "
                                          f"(default: {default('ego_speed')})"))
    if "risk" in stages:
        p.set_defaults(_risk_defaults=REAL_FRAMES_RISK if defaults.get("significant_velocity") == "on" else {})
        p.add_argument("--risk", default=default("risk"), metavar="NAME",
                       help=_RegistryHelp("risk", "risk estimator ({names}): ttc is the paper's 1/TTC, monte_carlo "
                                          "IDM/MOBIL rollouts, which take the ego speed from the ego-speed "
                                          f"estimator (default: {default('risk')})"))
    if "horizon" in stages:
        p.add_argument("--horizon", default=CALIBRATED, metavar="NAME",
                       help=_RegistryHelp("horizon", "horizon row of equation 3 ({names}): the calibration's every "
                                          "frame, or this frame's lane-line vanishing point (online; for a camera "
                                          "that pitches on its mount), or the calibration's plus the road's distance "
                                          "per row from the lane lines' spacing (lane_width; for roads that are not "
                                          f"flat; default: {CALIBRATED})"))


def _component(kind: str, option: str, name: str, kwargs: dict[str, Any] | None = None,
               check: bool = True) -> ComponentConfig:
    from monorarp.detection.model_file import is_model_path

    if check and not (kind == "detector" and is_model_path(name)):
        try:
            registry.get_factory(kind, name)
        except registry.UnknownComponentError as e:
            raise UserError(f"{option}: {e}") from None
    return ComponentConfig(name=name, kwargs=kwargs or {})


def pipeline_config(args: argparse.Namespace, base: PipelineConfig | None = None, check: bool = True) -> PipelineConfig:
    """The :class:`PipelineConfig` the options of :func:`add_pipeline_options` describe (stages without
    options as in ``base``, default :class:`PipelineConfig`). Raises :class:`UserError` (one line naming
    the option) for an option that does not apply and, with ``check``, for an unknown name (without it,
    :meth:`Pipeline.from_config` refuses unknown names, for a command that checks its inputs first)."""
    from monorarp.pipeline.detectors import is_centernet

    cfg = base if base is not None else PipelineConfig()
    stages = getattr(args, "_pipeline_stages", ())
    update: dict[str, ComponentConfig | None] = {}
    if "detector" in stages:
        name, kw = str(args.detector), {}
        refine = getattr(args, "refine_bottom", None)
        if refine is not None:
            if not is_centernet(name):
                raise UserError(f"--refine-bottom applies to the CenterNet detector, not {name!r}")
            kw["refine_bottom"] = refine == "on"
        weak = getattr(args, "weak_detections", None)
        if weak is not None:
            if not is_centernet(name):
                raise UserError(f"--weak-detections applies to the CenterNet detector, not {name!r}")
            if not 0 <= weak <= 1:
                raise UserError(f"--weak-detections must be a score in [0, 1], got {weak}")
            kw["weak_score_threshold"] = weak
        update["detector"] = _component("detector", "--detector", name, kw, check)
    if "tracker" in stages:
        update["tracker"] = _component("tracker", "--tracker", args.tracker, check=check)
        if "detector" in stages and getattr(args, "weak_detections", None) is not None:
            check_weak_detections(update["detector"], [args.tracker], "--weak-detections")
    if "state" in stages:
        kw = {**cfg.state.kwargs, **getattr(args, "_state_defaults", {}), "velocity": args.velocity}
        size = getattr(args, "size_prior", None)
        if size is not None:
            kw["size_prior"] = size == "on"
        update["state"] = ComponentConfig(name=cfg.state.name, kwargs=kw)
    if "risk" in stages:
        update["risk"] = _component("risk", "--risk", args.risk, _risk_defaults(args), check)
    if "ego_speed" in stages:
        ego = str(args.ego_speed)
        update["ego_speed"] = None if ego.lower() == NONE else _component("ego_speed", "--ego-speed", ego, check=check)
    if "horizon" in stages:
        update["horizon"] = None if args.horizon == CALIBRATED else _component("horizon", "--horizon", args.horizon,
                                                                                   check=check)
    warning = _warning_defaults(args, cfg.warning)
    if warning is not None:
        update["warning"] = warning
    return cfg.model_copy(update=update)


def _warning_defaults(args: argparse.Namespace, warning: ComponentConfig | None) -> ComponentConfig | None:
    """``warning`` with :data:`REAL_FRAMES_WARNING` under its own kwargs where the command asks for it and the
    stage is a :class:`~monorarp.warning.fcw.ForwardCollisionWarning`; None: leave it as it is."""
    kw = getattr(args, "_warning_defaults", {})
    if not kw or warning is None:
        return None
    from monorarp.warning.fcw import ForwardCollisionWarning

    try:
        factory = registry.get_factory("warning", warning.name)
    except registry.UnknownComponentError:
        return None   # refused by Pipeline.from_config, naming the kind
    if not (isinstance(factory, type) and issubclass(factory, ForwardCollisionWarning)):
        return None
    return ComponentConfig(name=warning.name, kwargs={**kw, **warning.kwargs})


def _risk_defaults(args: argparse.Namespace) -> dict[str, Any]:
    """:data:`REAL_FRAMES_RISK` where the command asks for it and ``--risk`` names a TTC estimator, else none."""
    kw = getattr(args, "_risk_defaults", {})
    if not kw:
        return {}
    from monorarp.risk.estimators import TTCRiskEstimator

    try:
        factory = registry.get_factory("risk", str(args.risk))
    except registry.UnknownComponentError:
        return {}   # refused with its option's name by _component (or by Pipeline.from_config)
    return dict(kw) if isinstance(factory, type) and issubclass(factory, TTCRiskEstimator) else {}


def default_pipeline_config(defaults: dict[str, str] | None = None) -> PipelineConfig:
    """What :func:`pipeline_config` gives for a command line with every stage's option left out
    (``defaults``: as :func:`add_pipeline_options`'s, e.g. :data:`REAL_FRAMES`)."""
    p = argparse.ArgumentParser(add_help=False)
    add_pipeline_options(p, defaults=defaults)
    return pipeline_config(p.parse_args([]))
