"""Scoring of one run: its results against the truth -> metrics, per-object records and per-frame rows.

Besides :func:`harness.scoring.evaluate.evaluate`, a run is scored against the paper's 1/TTC
risk on the same states (when its risk estimator is another one), and on the adverse-manoeuvre
1/TTC (:class:`monorarp.risk.estimators.ManoeuvreTTCRisk`, for the scorecard's risk table), and says where its risk
stage got the ego speed from (estimator, true speed with ``gps_speed``, or its own setting).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

from harness.scoring.evaluate import EvalConfig, evaluate
from harness.scoring.per_frame import frame_rows
from harness.world.truth import FrameTruth
from monorarp.core.camera import CameraModel
from monorarp.pipeline.config import PipelineConfig
from monorarp.pipeline.runner import Pipeline
from monorarp.pipeline.registry import build, uses
from monorarp.risk.estimators import TTCRiskEstimator
from monorarp.risk.ttc import HORIZON_S
from monorarp.core.types import FrameResult, RiskEstimate
from monorarp.warning.fcw import ForwardCollisionWarning


@dataclass
class RunScore:
    """The scores of a run: ``metrics`` (nested dict, NaN kept) and ``records`` (per object and frame)."""

    metrics: dict
    records: list
    truths: list[FrameTruth]
    results: list[FrameResult]
    eval_config: EvalConfig
    baseline: list[RiskEstimate] | None
    fcw_risk: list[float] | None = None
    manoeuvre_risk: list[float] | None = None

    def frame_rows(self) -> list[dict]:
        """The rows of ``per_frame.csv`` (:func:`harness.scoring.per_frame.frame_rows`)."""
        return frame_rows(self.truths, self.results, self.eval_config, self.baseline, self.fcw_risk,
                          self.manoeuvre_risk)


def score_run(truths: list[FrameTruth], results: list[FrameResult], cfg: PipelineConfig, pipeline: Pipeline,
              camera: CameraModel, eval_config: EvalConfig, wall_time_s: float, run_info: dict,
              gps_speed: bool) -> RunScore:
    """Score ``results`` against ``truths`` (the same frames, in order); ``wall_time_s``: the pipeline's."""
    baseline = baseline_ttc_risk(results, camera, pipeline)
    metrics, records = evaluate(truths, results, eval_config, wall_time_s=wall_time_s, run_info=run_info,
                                camera=camera, baseline_risk=baseline,
                                ego_speed_method=None if cfg.ego_speed is None else cfg.ego_speed.name,
                                fcw_threshold_s=getattr(pipeline.warning, "ttc_threshold_s", None))
    metrics["risk"]["ego_speed_sources"] = ego_speed_sources(results, pipeline, gps_speed)
    return RunScore(metrics, records, truths, results, eval_config, baseline, fcw_ttc_risk(results, pipeline),
                    manoeuvre_ttc_risk(results, camera))


def baseline_ttc_risk(results: list[FrameResult], camera: CameraModel,
                      pipeline: Pipeline) -> list[RiskEstimate] | None:
    """The paper's 1/TTC risk on the same states, when the run's risk estimator is another one (else None:
    the run's own risk is the paper's, :class:`monorarp.risk.estimators.TTCRiskEstimator` itself, not a subclass)."""
    if type(pipeline.risk) is TTCRiskEstimator:
        return None
    ttc = build("risk", "ttc", camera=camera)
    return [ttc.assess(r.states, r.t) for r in results]


def manoeuvre_ttc_risk(results: list[FrameResult], camera: CameraModel) -> list[float]:
    """Per frame, the adverse-manoeuvre 1/TTC (1/s) on the run's states, with its defaults."""
    stage = build("risk", "manoeuvre_ttc", camera=camera)
    return [stage.assess(r.states, r.t).risk for r in results]


def fcw_ttc_risk(results: list[FrameResult], pipeline: Pipeline) -> list[float] | None:
    """Per frame, 1 / the lowest in-path TTC (1/s; 0: none within 10 s) by the run's own ``fcw`` warning
    stage's rules (its sigma margins, looming veto, plausibility, ego-speed cap) with its threshold
    raised to the 10 s horizon: the warning decision as a continuous risk score. None without ``fcw``."""
    if not isinstance(pipeline.warning, ForwardCollisionWarning):
        return None
    stage = copy.copy(pipeline.warning)
    stage.ttc_threshold_s = HORIZON_S
    out = []
    for r in results:
        threats = stage.threats(r.states, r.ego_speed)
        out.append(max((1.0 / max(v, 0.1) for v in threats.values()), default=0.0))
    return out


def ego_speed_sources(results: list[FrameResult], pipeline: Pipeline, gps_speed: bool) -> dict[str, int] | None:
    """Frames whose risk stage got the ego speed from the estimator / the true speed / its own setting.

    None when the risk stage takes no ego speed (the 1/TTC risk works on relative velocities).
    """
    if not uses(pipeline.risk, "ego_speed"):
        return None
    n_est = sum(r.ego_speed is not None for r in results)
    rest = len(results) - n_est
    return {"estimator": n_est, "gps": rest if gps_speed else 0, "risk_default": 0 if gps_speed else rest}
