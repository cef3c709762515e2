"""The public import path of :mod:`monorarp.core.types` (plug-ins and users write ``monorarp.types``)."""

from monorarp.core.types import (  # noqa: F401 - re-exported
    Box,
    Frame,
    Detection,
    strong,
    Track,
    HorizonReading,
    ObjectState,
    RiskEstimate,
    WarningState,
    FrameResult,
    Detector,
    Tracker,
    StateEstimator,
    RiskEstimator,
    EgoSpeedEstimator,
    WarningStage,
    HorizonStage,
)

__all__ = ['Box', 'Frame', 'Detection', 'strong', 'Track', 'HorizonReading', 'ObjectState', 'RiskEstimate', 'WarningState', 'FrameResult', 'Detector', 'Tracker', 'StateEstimator', 'RiskEstimator', 'EgoSpeedEstimator', 'WarningStage', 'HorizonStage']
