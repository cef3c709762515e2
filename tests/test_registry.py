"""The registry is a mechanism only: built-ins come from the catalogue, lazily, with no import loop."""

from __future__ import annotations

import inspect
import subprocess
import sys

import pytest

from monorarp.pipeline import registry
from monorarp.core.camera import CameraModel
from monorarp.pipeline.catalogue import BUILTINS

CAM = CameraModel.from_fov(320, 180, 60.0, 1.3)
ENTRIES = [(kind, name, target) for kind, names in BUILTINS.items() for name, target in names.items()]


def _run(code: str) -> str:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()


def test_importing_the_registry_imports_no_component():
    loaded = _run("import sys, monorarp.pipeline.registry as r\n"
                  "r.available('tracker')\n"
                  "print(','.join(sorted(m for m in sys.modules if m.startswith(('monorarp', 'harness')))))")
    assert loaded.split(",") == ["monorarp", "monorarp.core", "monorarp.core.errors", "monorarp.pipeline",
                                   "monorarp.pipeline.catalogue", "monorarp.pipeline.registry"]


def test_no_component_module_imports_the_registry():
    modules = sorted({target.partition(":")[0] for _, _, target in ENTRIES} | {"harness.run.oracle"})
    loaded = _run(f"import importlib, sys\nfor m in {modules!r}: importlib.import_module(m)\n"
                  "print('monorarp.pipeline.registry' in sys.modules)")
    assert loaded == "False"


@pytest.mark.parametrize("kind,name,target", ENTRIES, ids=[f"{k}:{n}" for k, n, _ in ENTRIES])
def test_catalogue_entry_resolves_to_a_class_that_declares_what_it_takes(kind, name, target):
    cls = registry.get_factory(kind, name)
    assert inspect.isclass(cls) and f"{cls.__module__}:{cls.__qualname__}" == target
    params = inspect.signature(cls).parameters
    for what in ("camera", "seed"):
        assert registry.uses(cls, what) == (what in params), f"{target}: uses_{what} disagrees with its signature"


def test_stage_methods_take_the_uniform_keywords():
    for name in BUILTINS["state"]:
        assert "horizon" in inspect.signature(registry.get_factory("state", name).update).parameters
    for name in BUILTINS["risk"]:
        assert "ego_speed" in inspect.signature(registry.get_factory("risk", name).assess).parameters


def test_only_risks_that_need_the_ego_speed_say_so():
    assert [n for n in BUILTINS["risk"] if registry.uses(registry.get_factory("risk", n), "ego_speed")] == \
        ["monte_carlo"]


def test_each_builtin_is_declared_once():
    from importlib.metadata import entry_points

    for kind in registry.KINDS:
        plugged = {ep.name for ep in entry_points(group=f"monorarp.{kind}")}
        assert not plugged & set(BUILTINS[kind]), kind


def test_oracle_is_a_plugin_entry_point():
    from harness.run.oracle import OracleDetector

    assert "oracle" in registry.available("detector")
    assert registry.get_factory("detector", "oracle") is OracleDetector


def test_build_gives_the_camera_only_to_factories_that_use_it():
    class Plain:
        def __init__(self, **kw):
            self.kw = kw

    class WithCamera(Plain):
        uses_camera = True

    registry.add("tracker", "_plain", Plain)
    registry.add("tracker", "_cam", WithCamera)
    try:
        assert registry.build("tracker", "_plain", {}, CAM).kw == {}
        assert registry.build("tracker", "_cam", {}, CAM).kw == {"camera": CAM}
        assert registry.build("tracker", "_cam", {"camera": "mine"}, CAM).kw == {"camera": "mine"}
        assert registry.build("tracker", "_cam", {}, None).kw == {}
    finally:
        registry.remove("tracker", "_plain")
        registry.remove("tracker", "_cam")
    assert "_plain" not in registry.available("tracker")


def test_add_takes_a_module_class_string_and_wins_over_the_catalogue():
    registry.add("tracker", "particle", "monorarp.tracking.sort:SortTracker")
    try:
        assert registry.get_factory("tracker", "particle").__name__ == "SortTracker"
    finally:
        registry.remove("tracker", "particle")
    assert registry.get_factory("tracker", "particle").__name__ == "ParticleTracker"


def test_unknown_name_and_kind():
    with pytest.raises(registry.UnknownComponentError, match="unknown tracker 'nope'; available: .*particle"):
        registry.get_factory("tracker", "nope")
    with pytest.raises(ValueError, match="unknown component kind"):
        registry.add("trackers", "x", object)
