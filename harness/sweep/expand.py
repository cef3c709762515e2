"""Expand a sweep spec into runs: scenarios x seeds x grid product x variants, in that nesting order.

A run id reads ``<scenario file stem>__seed<seed>__<field>=<value>...__<variant>``,
e.g. ``highway_cruise__seed1__camera.pitch_deg=4__kcf``: only characters
``[A-Za-z0-9._=+-]`` (others become ``_``), so ids are file names. Ids depend
only on the run's parameters, never on its position, so they are stable when
the spec grows.

Everything that can be checked without running is checked here, before any
run starts (:func:`expand` raises :class:`~harness.sweep.spec.SweepSpecError`):
scenario files exist and validate, every variant's components resolve and
build (unknown names, bad kwargs, missing ``.onnx`` files). A grid combination
whose *values* make the scenario invalid (e.g. an ego lane off a narrowed road)
is not a spec error: that run is expanded with ``error`` set and recorded as
failed without being executed, the others go on.
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import math
import re
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from harness.world.scenario import ScenarioError, load_scenario_dict, parse_scenario
from harness.sweep.spec import SweepSpec, SweepSpecError, apply_override, load_sweep_spec, run_mapping
from monorarp.core.errors import UserError

MAX_ID_LENGTH = 180


@dataclass(frozen=True)
class RunTask:
    """One run of a sweep; plain data (picklable, JSON-able) handed to executors."""

    id: str
    index: int                         # position in the deterministic expansion order
    scenario_file: str                 # as written in the spec
    scenario_key: str                  # file stem, the id's first part
    seed: int
    grid: dict[str, Any]               # grid values of this run, in spec order
    variant: str
    scenario: dict | None              # validated scenario mapping (JSON types); None when invalid
    pipeline: dict                     # PipelineConfig mapping, seeds injected
    frames: int | None
    warning_threshold_s: float
    annotate: bool = False
    error: str | None = None           # expansion-time error: the run is recorded as failed, never executed
    cache_dir: str | None = None       # frame cache (harness.run.frame_cache); not a parameter: same metrics without
    cache_max_bytes: int | None = None

    def params(self) -> dict:
        """Everything that determines this run's metrics (stored in ``run.json``, compared on resume)."""
        d = asdict(self)
        for k in ("index", "error", "cache_dir", "cache_max_bytes"):
            d.pop(k)
        return d

    def frames_key(self) -> str | None:
        """Runs with the same key render the same frames (scenario mapping and frame cap); None: this run renders
        nothing, or has no frame cache to share them through."""
        if self.cache_dir is None or self.scenario is None or self.error is not None:
            return None
        return json.dumps([self.scenario, self.frames], sort_keys=True)


@dataclass
class Expansion:
    spec: SweepSpec
    spec_path: Path
    tasks: list[RunTask] = field(default_factory=list)


# ----------------------------------------------------------------------- ids
def format_value(v: Any) -> str:
    """Short, stable text of a grid value: ``4.0`` -> ``4``, ``12.19`` -> ``12.19``, ``[20, 25]`` -> ``20-25``."""
    if v is None:
        return "null"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return str(int(v)) if math.isfinite(v) and v.is_integer() and abs(v) < 1e15 else repr(v)
    if isinstance(v, (list, tuple)):
        return "-".join(format_value(x) for x in v)
    return str(v)


def sanitize(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9._=+\-]", "_", text)


def run_id(scenario_key: str, seed: int, grid: dict[str, Any], variant: str) -> str:
    parts = [scenario_key, f"seed{seed}", *(f"{k}={format_value(v)}" for k, v in grid.items()), variant]
    rid = sanitize("__".join(parts))
    if len(rid) > MAX_ID_LENGTH:   # keep it a valid file name; the hash keeps it unique
        digest = hashlib.sha1(rid.encode()).hexdigest()[:10]
        rid = f"{rid[:MAX_ID_LENGTH - 12]}__{digest}"
    return rid


# -------------------------------------------------------------- components
def _camera_for_preflight(scenarios: list[dict]):
    from harness.world.scenario import Camera

    for data in scenarios:
        try:
            return parse_scenario(data).camera.model()
        except ScenarioError:
            continue
    return Camera().model()


def inject_seeds(pipeline: dict, seed: int) -> dict:
    """Give every component whose factory declares ``uses_seed`` the run's seed, unless the spec set one."""
    from monorarp.detection.model_file import is_model_path
    from monorarp.pipeline.registry import get_factory, uses

    out = copy.deepcopy(pipeline)
    for kind, comp in out.items():
        if comp is None or is_model_path(comp["name"]) or "seed" in comp["kwargs"]:
            continue
        if uses(get_factory(kind, comp["name"]), "seed"):
            comp["kwargs"]["seed"] = int(seed)
    return out


def check_components(spec: SweepSpec, spec_path: Path, scenarios: list[dict]) -> dict[str, dict]:
    """Each variant's pipeline mapping, after building it once (raises :class:`SweepSpecError`)."""
    from monorarp.detection.model_file import is_model_path
    from monorarp.pipeline.runner import Pipeline

    camera = _camera_for_preflight(scenarios)
    configs = {}
    for i, variant in enumerate(spec.variants):
        cfg = variant.pipeline_config(spec_path.parent)
        where = f"{spec_path}: variants.{i} ({variant.name})"
        det = cfg.detector.name
        if is_model_path(det) and not Path(det).is_file():
            raise SweepSpecError(f"{where}: detector: no such ONNX file {det}")
        try:
            Pipeline.from_config(cfg, camera)
        except UserError as e:
            raise SweepSpecError(f"{where}: {e}") from None
        except Exception as e:  # noqa: BLE001 - bad kwargs etc. from a component constructor
            raise SweepSpecError(f"{where}: cannot build the pipeline: {type(e).__name__}: {e}") from None
        configs[variant.name] = run_mapping(cfg)
    return configs


# ---------------------------------------------------------------- expansion
def _load_scenarios(spec: SweepSpec, spec_path: Path) -> list[tuple[str, str, dict]]:
    """(file as written, stem, mapping with spec-wide and per-scenario overrides) per scenario entry."""
    out = []
    stems: dict[str, str] = {}
    for i, ref in enumerate(spec.scenarios):
        path = Path(ref.file).expanduser()
        path = path if path.is_absolute() else spec_path.parent / path
        if not path.is_file():
            raise SweepSpecError(f"{spec_path}: scenarios.{i}: no such scenario file {ref.file} (looked for {path})")
        data = load_scenario_dict(path)
        if not isinstance(data, dict):
            raise SweepSpecError(f"{spec_path}: scenarios.{i}: {path} is not a YAML mapping")
        for where, overrides in (("overrides", spec.overrides), (f"scenarios.{i}.overrides", ref.overrides)):
            for key, value in overrides.items():
                try:
                    apply_override(data, key, value)
                except ValueError as e:
                    raise SweepSpecError(f"{spec_path}: {where}: {e}") from None
        for key, values in spec.grid.items():   # structural check (e.g. a vehicle name the file lacks)
            try:
                apply_override(copy.deepcopy(data), key, values[0])
            except ValueError as e:
                raise SweepSpecError(f"{spec_path}: grid: {ref.file}: {e}") from None
        try:
            parse_scenario(data, path)   # the base scenario itself must be valid
        except ScenarioError as e:
            raise SweepSpecError(f"{spec_path}: scenarios.{i}: {e}") from None
        stem = sanitize(path.stem)
        if stem in stems:
            raise SweepSpecError(f"{spec_path}: scenarios.{i}: {ref.file} has the same name {stem!r} as "
                                 f"{stems[stem]}; run ids would collide")
        stems[stem] = ref.file
        out.append((ref.file, stem, data))
    return out


def expand(spec: SweepSpec, spec_path: str | Path, annotate: bool = False) -> Expansion:
    """All runs of ``spec`` in deterministic order; everything checkable is checked first."""
    spec_path = Path(spec_path)
    scenarios = _load_scenarios(spec, spec_path)
    pipelines = check_components(spec, spec_path, [d for _, _, d in scenarios])
    keys = list(spec.grid)
    combos = list(itertools.product(*(spec.grid[k] for k in keys))) if keys else [()]
    exp = Expansion(spec=spec, spec_path=spec_path)
    seen: dict[str, RunTask] = {}
    for file, stem, base in scenarios:
        seeds = spec.seeds if spec.seeds is not None else [int(base.get("seed", 0) or 0)]
        for seed in seeds:
            for combo in combos:
                grid = dict(zip(keys, combo))
                scenario, error = _scenario_for(base, seed, grid, file)
                for variant in spec.variants:
                    rid = run_id(stem, seed, grid, variant.name)
                    if rid in seen:
                        raise SweepSpecError(f"{spec_path}: two runs get the same id {rid!r} "
                                             f"(grid values that print the same?)")
                    task = RunTask(id=rid, index=len(exp.tasks), scenario_file=file, scenario_key=stem, seed=seed,
                                   grid=grid, variant=variant.name, scenario=scenario,
                                   pipeline=inject_seeds(pipelines[variant.name], seed), frames=spec.frames,
                                   warning_threshold_s=spec.warning_threshold_s, annotate=annotate, error=error)
                    seen[rid] = task
                    exp.tasks.append(task)
    return exp


def _scenario_for(base: dict, seed: int, grid: dict[str, Any], file: str) -> tuple[dict | None, str | None]:
    data = copy.deepcopy(base)
    data["seed"] = int(seed)
    try:
        for key, value in grid.items():
            apply_override(data, key, value)
        scenario = parse_scenario(data, file)
    except (ValueError, ScenarioError) as e:
        shown = ", ".join(f"{k}={format_value(v)}" for k, v in grid.items())
        return None, f"invalid scenario for {shown or 'this run'}: {e}"
    return scenario.model_dump(mode="json"), None


def load_and_expand(path: str | Path, annotate: bool = False) -> Expansion:
    """:func:`load_sweep_spec` then :func:`expand`."""
    return expand(load_sweep_spec(path), path, annotate=annotate)
