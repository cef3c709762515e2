"""Sweep-spec YAML: scenarios x seeds x a grid over scenario fields x pipeline variants.

Example (paths are relative to the spec file)::

    name: trackers
    scenarios: [highway_cruise.yaml, {file: lead_braking.yaml, overrides: {duration_s: 4}}]
    seeds: [1, 2]                      # omitted: each scenario's own seed
    grid: {camera.pitch_deg: [1, 3]}   # dotted scenario fields; the full product is run
    overrides: {camera.width: 640}     # applied to every scenario (not part of run ids)
    frames: 60                         # cap per run (null: the scenario's duration x fps)
    warning_threshold_s: 2.0
    metrics: [distance.rel_err_median] # headline metrics shown first in the report
    variants:
      - {name: particle, detector: oracle, tracker: particle}
      - {name: kcf, detector: oracle, tracker: kcf, velocity: difference}

Every override path (grid, ``overrides``, per-scenario ``overrides``) is checked
against the scenario schema (:class:`harness.world.scenario.Scenario`) when the spec
is loaded; list items are addressed by index (``vehicles.0.speed_mps``) or, for
named items, by name (``vehicles.lead.speed_mps``). Unknown keys are rejected;
errors name the file and the field.
"""

from __future__ import annotations

import types
import typing
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from harness.world.config_io import Seed, validate_config
from harness.world.scenario import Scenario
from monorarp.warning.thresholds import TTC_CUE_THRESHOLD_S
from monorarp.core.errors import UserError
from monorarp.core.readers import read_yaml
from monorarp.pipeline.config import ComponentConfig, PipelineConfig

_DEFAULT = PipelineConfig()
_NAME = r"^[A-Za-z0-9][A-Za-z0-9_.+\-]*$"


class SweepSpecError(UserError, ValueError):
    """An invalid sweep spec; the message names the file, the field and the reason."""


# --------------------------------------------------------------- override paths
def _unwrap(tp: Any) -> Any:
    """Strip ``Annotated`` and ``X | None``."""
    while typing.get_origin(tp) is Annotated:
        tp = typing.get_args(tp)[0]
    if typing.get_origin(tp) in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        if len(args) == 1:
            return _unwrap(args[0])
    return tp


def _union_members(tp: Any) -> list[Any]:
    tp = _unwrap(tp)
    if typing.get_origin(tp) in (typing.Union, types.UnionType):
        return [_unwrap(a) for a in typing.get_args(tp) if a is not type(None)]
    return [tp]


def _is_model(tp: Any) -> bool:
    return isinstance(tp, type) and issubclass(tp, BaseModel)


def check_override_path(path: str, root: type[BaseModel] = Scenario) -> None:
    """Raise ``ValueError`` unless ``path`` (dotted) names a field of the scenario schema.

    List items may be addressed by index or (for items with a ``name``) by name;
    fixed-length tuples by index.
    """
    parts = path.split(".")
    if not path or any(p == "" for p in parts):
        raise ValueError(f"{path!r} is not a dotted field path")
    types_here: list[Any] = [root]
    done = ""
    for part in parts:
        nxt: list[Any] = []
        for tp in types_here:
            tp = _unwrap(tp)
            origin = typing.get_origin(tp)
            if _is_model(tp):
                if part in tp.model_fields:
                    nxt.extend(_union_members(tp.model_fields[part].annotation))
            elif origin is list:
                item = typing.get_args(tp)[0]
                named = any(_is_model(m) and "name" in m.model_fields for m in _union_members(item))
                if part.lstrip("-").isdigit() or named:
                    nxt.extend(_union_members(item))
            elif origin is tuple:
                args = typing.get_args(tp)
                if part.isdigit() and int(part) < len(args):
                    nxt.extend(_union_members(args[int(part)]))
        if not nxt:
            where = f"under {done!r}" if done else "at the top level of a scenario"
            raise ValueError(f"{path!r}: no field {part!r} {where}")
        types_here = nxt
        done = f"{done}.{part}" if done else part


def apply_override(data: dict, path: str, value: Any) -> None:
    """Set ``data[path]`` in place (dotted path; intermediate mappings are created).

    Raises ``ValueError`` when a list item addressed by index or name is absent.
    """
    parts = path.split(".")
    node: Any = data
    for i, part in enumerate(parts):
        last = i == len(parts) - 1
        here = ".".join(parts[: i + 1])
        if isinstance(node, dict):
            if last:
                node[part] = value
                return
            child = node.get(part)
            if child is None:
                child = node[part] = {}
            node = child
        elif isinstance(node, list):
            idx = _list_index(node, part, here)
            if last:
                node[idx] = value
                return
            node = node[idx]
        else:
            raise ValueError(f"{here}: cannot set a field inside a {type(node).__name__} value")


def _list_index(items: list, part: str, here: str) -> int:
    if part.lstrip("-").isdigit():
        idx = int(part)
        if not -len(items) <= idx < len(items):
            raise ValueError(f"{here}: the scenario has {len(items)} item(s) there, no index {idx}")
        return idx
    for j, item in enumerate(items):
        if isinstance(item, dict) and item.get("name") == part:
            return j
    raise ValueError(f"{here}: the scenario has no item named {part!r}")


# ------------------------------------------------------------------- schema
class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


def _check_paths(paths: dict[str, Any]) -> dict[str, Any]:
    for p in paths:
        check_override_path(p)
    return paths


class ScenarioRef(_Model):
    """A scenario file (relative to the spec) with optional overrides applied to it alone."""

    file: str = Field(min_length=1)
    overrides: dict[str, Any] = {}

    @field_validator("overrides")
    @classmethod
    def _paths(cls, v: dict[str, Any]) -> dict[str, Any]:
        return _check_paths(v)


class Variant(_Model):
    """One pipeline configuration in the spec file's flat form (``<stage>`` and ``<stage>_kwargs``);
    :meth:`pipeline_config` is the one place it becomes a :class:`PipelineConfig`, whose defaults it
    takes (no ego-speed stage unless one is named). Component names resolve through :mod:`monorarp.pipeline.registry`.

    ``detector`` is a registered name, ``oracle`` (ground-truth boxes) or an
    ``.onnx`` path (relative to the spec file). ``velocity`` is shorthand for
    ``state_kwargs.velocity`` of the geometric state estimator.
    """

    name: str = Field(pattern=_NAME, max_length=60)
    detector: str = _DEFAULT.detector.name
    detector_kwargs: dict[str, Any] = {}
    tracker: str = _DEFAULT.tracker.name
    tracker_kwargs: dict[str, Any] = {}
    state: str = _DEFAULT.state.name
    state_kwargs: dict[str, Any] = {}
    velocity: Literal["kalman", "difference"] | None = None
    risk: str = _DEFAULT.risk.name
    risk_kwargs: dict[str, Any] = {}
    ego_speed: str | None = None
    ego_speed_kwargs: dict[str, Any] = {}
    warning: str | None = _DEFAULT.warning.name
    warning_kwargs: dict[str, Any] = {}
    horizon: str | None = Field(None, description="horizon stage (monorarp.horizon.stages: calibrated, online); "
                                                  "null: the calibrated horizon, no stage")
    horizon_kwargs: dict[str, Any] = {}

    @model_validator(mode="after")
    def _velocity(self) -> "Variant":
        if self.velocity is not None and "velocity" in self.state_kwargs:
            raise ValueError("give velocity either as 'velocity' or in 'state_kwargs', not both")
        return self

    def pipeline_config(self, spec_dir: Path) -> PipelineConfig:
        """This variant's :class:`PipelineConfig`; a relative ``.onnx`` detector path is made absolute
        against ``spec_dir`` (the spec file's folder)."""
        from monorarp.detection.model_file import is_model_path

        detector = self.detector
        if is_model_path(detector):
            p = Path(detector).expanduser()
            detector = str(p if p.is_absolute() else (spec_dir / p).resolve())
        state_kwargs = dict(self.state_kwargs)
        if self.velocity is not None:
            state_kwargs["velocity"] = self.velocity

        def comp(name: str | None, kwargs: dict[str, Any]) -> ComponentConfig | None:
            return None if name is None else ComponentConfig(name=name, kwargs=dict(kwargs))

        return PipelineConfig(detector=comp(detector, self.detector_kwargs),
                              tracker=comp(self.tracker, self.tracker_kwargs),
                              state=comp(self.state, state_kwargs), risk=comp(self.risk, self.risk_kwargs),
                              ego_speed=comp(self.ego_speed, self.ego_speed_kwargs),
                              warning=comp(self.warning, self.warning_kwargs),
                              horizon=comp(self.horizon, self.horizon_kwargs))


def run_mapping(config: PipelineConfig) -> dict:
    """``config`` as a run stores it (``RunTask.pipeline``, ``run.json``, compared on ``--resume``): a
    mapping without a ``horizon`` key when there is no horizon stage, as runs before that stage have it."""
    data = config.model_dump()
    if data["horizon"] is None:
        del data["horizon"]
    return data


GridValue = bool | int | float | str | list[bool | int | float | str] | None


class SweepSpec(_Model):
    name: str = Field(pattern=_NAME, max_length=80)
    scenarios: list[ScenarioRef] = Field(min_length=1)
    seeds: list[Seed] | None = Field(None, min_length=1)
    grid: dict[str, list[GridValue]] = {}
    overrides: dict[str, Any] = {}
    frames: int | None = Field(None, gt=0)
    warning_threshold_s: float = Field(TTC_CUE_THRESHOLD_S, gt=0, le=30)
    metrics: list[str] = []
    variants: list[Variant] = Field(default_factory=lambda: [Variant(name="default")], min_length=1)

    @field_validator("scenarios", mode="before")
    @classmethod
    def _scenario_strings(cls, v: Any) -> Any:
        return [{"file": s} if isinstance(s, str) else s for s in v] if isinstance(v, list) else v

    @field_validator("overrides")
    @classmethod
    def _paths(cls, v: dict[str, Any]) -> dict[str, Any]:
        return _check_paths(v)

    @field_validator("grid")
    @classmethod
    def _grid(cls, grid: dict[str, list]) -> dict[str, list]:
        for path, values in grid.items():
            check_override_path(path)
            if not values:
                raise ValueError(f"{path!r}: give at least one value")
            if len({repr(v) for v in values}) != len(values):
                raise ValueError(f"{path!r}: repeated values {values}")
        return grid

    @field_validator("seeds")
    @classmethod
    def _seeds(cls, seeds: list[int] | None) -> list[int] | None:
        if seeds is not None and len(set(seeds)) != len(seeds):
            raise ValueError(f"repeated seeds {seeds}")
        return seeds

    @field_validator("variants")
    @classmethod
    def _variants(cls, variants: list[Variant]) -> list[Variant]:
        names = [v.name for v in variants]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ValueError(f"repeated variant names {dup}")
        return variants



# ------------------------------------------------------------------- loading
def parse_sweep_spec(data: Any, source: str | Path = "<sweep spec>") -> SweepSpec:
    """Validate an already-loaded mapping; raises :class:`SweepSpecError`."""
    return validate_config(SweepSpec, data, source, SweepSpecError, "sweep spec")


def load_sweep_spec(path: str | Path) -> SweepSpec:
    """Read and validate a sweep-spec YAML file (structure only; see :func:`harness.sweep.expand.expand`)."""
    data = read_yaml(path, "sweep spec", SweepSpecError)
    return parse_sweep_spec(data, path)
