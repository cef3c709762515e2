"""Which component fills each pipeline stage: :class:`PipelineConfig` (the one place of every stage's
default) of :class:`ComponentConfig` (a registry name and its keyword arguments)."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from monorarp.core.errors import UserError
from monorarp.detection.model_file import is_model_path
from monorarp.pipeline import registry


class ComponentConfig(BaseModel):
    """A component chosen by registry name, with its constructor keyword arguments."""

    model_config = ConfigDict(extra="forbid")
    name: str
    kwargs: dict[str, Any] = Field(default_factory=dict)


#: The detector where the frames are real (``monorarp video``, ``monorarp eval kitti``): COCO-trained YOLOX-Nano.
#: :class:`PipelineConfig`'s own (``centernet``, trained on renders) is the simulation commands' (docs/pipeline.md).
REAL_WORLD_DETECTOR = "yolox"


class PipelineConfig(BaseModel):
    """Which component fills each stage: the one place of every stage's default (the detector's on
    simulated frames; on real ones :data:`REAL_WORLD_DETECTOR`). ``ego_speed``, ``warning``
    and ``horizon`` are optional (None = no such stage; no horizon stage = the calibrated horizon). The
    detector is a registered name or an ``.onnx`` path (:func:`monorarp.pipeline.detectors.build_detector`)."""

    model_config = ConfigDict(extra="forbid")
    detector: ComponentConfig = ComponentConfig(name="centernet")
    tracker: ComponentConfig = ComponentConfig(name="particle")
    state: ComponentConfig = ComponentConfig(name="geometric")
    risk: ComponentConfig = ComponentConfig(name="ttc")
    ego_speed: ComponentConfig | None = None
    warning: ComponentConfig | None = ComponentConfig(name="fcw")
    horizon: ComponentConfig | None = None

    def stages(self) -> dict[str, ComponentConfig]:
        """The configured stages by kind (absent optional stages left out), in pipeline order."""
        return {k: c for k in type(self).model_fields if (c := getattr(self, k)) is not None}

    def validate_names(self) -> "PipelineConfig":
        """Raise :class:`~monorarp.pipeline.registry.UnknownComponentError` (one line, naming the kind and the
        available names) for any unknown component name, before anything is built; returns ``self``."""
        for kind, comp in self.stages().items():
            if not (kind == "detector" and is_model_path(comp.name)):
                registry.get_factory(kind, comp.name)
        check_weak_detections(self.detector, [self.tracker.name])
        return self


#: The detector kwarg that turns weak detections on (``--weak-detections``).
WEAK_KWARG = "weak_score_threshold"


def check_weak_detections(detector: ComponentConfig, trackers: Iterable[str],
                          option: str = f"detector_kwargs.{WEAK_KWARG}") -> None:
    """Raise :class:`~monorarp.core.errors.UserError` (one line naming ``option``) when ``detector`` is set to
    give weak detections but none of ``trackers`` takes them (``uses_weak_detections``): they would be
    dropped silently. Unknown tracker names are left to :meth:`PipelineConfig.validate_names`."""
    if detector.kwargs.get(WEAK_KWARG) is None:
        return
    names = list(trackers)

    def takes(name: str) -> bool:
        return registry.uses(registry.get_factory("tracker", name), "weak_detections")

    try:
        if not names or any(takes(n) for n in names):
            return
    except registry.UnknownComponentError:
        return
    takers = []
    for n in registry.available("tracker"):
        try:
            takers += [n] if takes(n) else []
        except Exception:  # noqa: BLE001 - a plug-in that does not load is no taker
            pass
    raise UserError(f"{option}: weak detections go only to a tracker that takes them ({', '.join(takers) or 'none'}); "
                    f"{'tracker' if len(names) == 1 else 'trackers'} {', '.join(map(repr, names))} "
                    f"{'takes' if len(names) == 1 else 'take'} none")
