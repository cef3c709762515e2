"""The one declaration of every built-in component: ``"module:Class"`` per kind and name.

Nothing is imported here; :mod:`monorarp.pipeline.registry` imports a class when it is first asked for.
Plug-ins from other packages declare entry points in the groups ``monorarp.<kind>`` instead
(``docs/components.md``).
"""

from __future__ import annotations

BUILTINS: dict[str, dict[str, str]] = {
    "detector": {
        "centernet": "monorarp.detection.centernet:CenterNetDetector",
        "centernet_robust": "monorarp.detection.centernet:RobustCenterNetDetector",
        "centernet_dense": "monorarp.detection.centernet:DenseCenterNetDetector",
        "centernet_realistic": "monorarp.detection.centernet:RealisticCenterNetDetector",
        "centernet_street": "monorarp.detection.centernet:StreetCenterNetDetector",
        "yolo": "monorarp.detection.yolo:YoloDetector",
        "yolox": "monorarp.detection.yolox:YoloxDetector",
    },
    "tracker": {
        "particle": "monorarp.tracking.particle:ParticleTracker",
        "sort": "monorarp.tracking.sort:SortTracker",
        "bytetrack": "monorarp.tracking.bytetrack:ByteTracker",
        "kcf": "monorarp.tracking.opencv:KCFTracker",
        "csrt": "monorarp.tracking.opencv:CSRTTracker",
        "mosse": "monorarp.tracking.opencv:MOSSETracker",
        "medianflow": "monorarp.tracking.opencv:MedianFlowTracker",
    },
    "state": {
        "geometric": "monorarp.state.estimator:StateEstimator",
    },
    "risk": {
        "ttc": "monorarp.risk.estimators:TTCRiskEstimator",
        "manoeuvre_ttc": "monorarp.risk.estimators:ManoeuvreTTCRisk",
        "monte_carlo": "monorarp.risk.monte_carlo.estimator:MonteCarloRisk",
    },
    "ego_speed": {
        "ground_track": "monorarp.ego_speed.ground_track:GroundTrackEgoSpeed",
        "lsd_period": "monorarp.ego_speed.lsd_period:LsdPeriodEgoSpeed",
    },
    "warning": {
        "fcw": "monorarp.warning.fcw:ForwardCollisionWarning",
    },
    "horizon": {
        "calibrated": "monorarp.horizon.stages:CalibratedHorizon",
        "online": "monorarp.horizon.stages:OnlineHorizon",
        "lane_width": "monorarp.horizon.stages:LaneWidthRanging",
    },
}
