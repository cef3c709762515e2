"""Shared synthetic inputs for the tests: tiny scenario documents (straight 3-lane road, no random traffic)."""

from __future__ import annotations


def vehicle(name: str, lane: int, distance_m: float, speed_mps: float) -> dict:
    """A scripted vehicle at constant speed."""
    return {"name": name, "lane": lane, "distance_m": distance_m, "speed_mps": speed_mps,
            "behaviour": "constant_speed"}


def tiny_scenario(name: str, seed: int, vehicles: list[dict], width: int = 320, height: int = 180) -> dict:
    """A 1 s, 15 fps scenario on a 3-lane road, ego in lane 1 at 25 m/s, with only the given vehicles."""
    return {
        "name": name, "seed": seed, "duration_s": 1.0, "fps": 15,
        "road": {"lanes": 3}, "traffic": {"vehicles_count": 0},
        "ego": {"lane": 1, "speed_mps": 25},
        "vehicles": vehicles,
        "camera": {"width": width, "height": height},
    }


def write_scenario(path, data: dict):
    """Write a scenario document as YAML (keys in the given order) to `path`; returns `path`."""
    import yaml

    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def assert_scenario_rejected(build, *args, field: str) -> None:
    """``build(*args)`` raises ScenarioError with a one-line message naming ``field``."""
    import pytest

    from harness.world.scenario import ScenarioError

    with pytest.raises(ScenarioError) as e:
        build(*args)
    assert field in str(e.value) and "\n" not in str(e.value)
