"""Bad scenario files: ``monorarp render`` exits 2 with one line naming file and field, writes nothing."""

from __future__ import annotations

import textwrap

import pytest

from harness.world.scenario import ScenarioError, load_scenario
from monorarp.app.cli import main

# (id, YAML text, substrings the one-line message must contain)
BAD = [
    ("malformed_yaml", "name: x\nroad: [1, 2\nfps: 3\n", ["invalid YAML", "line 3"]),
    ("unknown_key", "name: x\nroad:\n  lanez: 3\n", ["road.lanez", "Extra inputs"]),
    ("out_of_range", "name: x\nfps: 500\n", ["fps", "less than or equal to 120"]),
    ("wrong_type", "name: x\nroad:\n  lanes: three\n", ["road.lanes", "integer"]),
    ("ego_lane_off_road", "name: x\nroad:\n  lanes: 3\nego:\n  lane: 3\n", ["ego.lane", "3-lane road"]),
    ("vehicle_lane_off_road", "name: x\nvehicles:\n  - {name: lead, distance_m: 20, lane: 3}\n",
     ["vehicles.0.lane", "off the road"]),
    ("event_unknown_vehicle",
     "name: x\nvehicles:\n  - {name: lead, distance_m: 20}\n"
     "events:\n  - {type: brake, vehicle: ghost, at_s: 1, decel_mps2: 5}\n",
     ["events.0.vehicle", "ghost"]),
    ("event_unknown_type", "name: x\nevents:\n  - {type: teleport, vehicle: ego, at_s: 1}\n",
     ["events.0", "teleport"]),
    # 640x360, hfov 70 deg: fy = 320/tan(35 deg) = 457 px, horizon = 179.5 - 457*tan(30 deg) = -84 px
    ("camera_horizon_outside_image", "name: x\ncamera:\n  pitch_deg: 30\n", ["camera", "horizon"]),
    ("warm_up_with_events",
     "name: x\ntraffic:\n  warmup_s: 3\nvehicles:\n  - {name: lead, distance_m: 20}\n"
     "events:\n  - {type: brake, vehicle: lead, at_s: 1, decel_mps2: 5}\n",
     ["traffic.warmup_s", "without events"]),
    ("warm_up_too_long", "name: x\ntraffic:\n  warmup_s: 61\n", ["traffic.warmup_s", "60"]),
    ("missing_name", "seed: 3\n", ["name", "required"]),
    ("seed_negative", "name: x\nseed: -1\n", ["seed", "greater than or equal to 0"]),
    ("seed_bool", "name: x\nseed: true\n", ["seed", "valid integer"]),
    ("seed_string", "name: x\nseed: \"7\"\n", ["seed", "valid integer"]),
    ("palette_seed_negative", "name: x\nrender: {palette_seed: -2}\n", ["render.palette_seed"]),
    ("name_absolute", "name: /tmp/x\n", ["name", "not a plain name"]),
    ("name_escapes", "name: ../escaped\n", ["name", "not a plain name"]),
    ("name_empty", "name: ''\n", ["name", "not a plain name"]),
    ("name_newline", "name: \"x\\n\"\n", ["name", "not a plain name"]),
    ("light_direction_nan", "name: x\nrender: {light_direction: [.nan, 0, -1]}\n",
     ["render.light_direction.0", "finite"]),
    ("light_direction_inf", "name: x\nrender: {light_direction: [0, .inf, -1]}\n",
     ["render.light_direction.1", "finite"]),
    ("light_direction_zero", "name: x\nrender: {light_direction: [0, 0, 0]}\n", ["light_direction", "non-zero"]),
    ("duplicate_key", "name: x\nseed: 1\nseed: 2\n", ["line 3", "duplicate key 'seed'", "first at line 2"]),
    ("duplicate_nested_key", "name: x\nroad:\n  lanes: 3\n  lanes: 4\n",
     ["line 4", "duplicate key 'lanes'", "first at line 3"]),
    ("duplicate_flow_key", "name: x\nvehicles: [{name: a, distance_m: 10, name: b}]\n", ["duplicate key 'name'"]),
    ("not_a_mapping", "- a\n- b\n", ["mapping"]),
    ("empty_file", "", ["mapping"]),
]


def _run(capsys, args):
    rc = main(args)
    err = capsys.readouterr().err
    return rc, err


@pytest.mark.parametrize("case_id,text,needles", BAD, ids=[b[0] for b in BAD])
def test_bad_scenario_one_line_exit_2_nothing_written(tmp_path, capsys, case_id, text, needles):
    path = tmp_path / f"{case_id}.yaml"
    path.write_text(text)
    out = tmp_path / "out"
    rc, err = _run(capsys, ["render", str(path), "--out", str(out)])
    assert rc == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert str(path) in lines[0]
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    assert "Traceback" not in err
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]
    with pytest.raises(ScenarioError):
        load_scenario(path)


# Valid for the schema, rejected by the simulation before anything is rendered or written.
SIM_BAD = [
    ("stationary_vehicle_brakes",
     "name: x\nvehicles: [{name: p, distance_m: 20, behaviour: stationary}]\n"
     "events: [{type: brake, vehicle: p, at_s: 1, decel_mps2: 3}]\n",
     ["events.0", "stationary"]),
    ("road_too_short", "name: x\nroad: {lanes: 1, length_m: 200}\nego: {lane: 0}\n", ["road.length_m"]),
]


@pytest.mark.parametrize("case_id,text,needles", SIM_BAD, ids=[b[0] for b in SIM_BAD])
def test_simulation_rejects_scenario_cleanly(tmp_path, capsys, case_id, text, needles):
    path = tmp_path / f"{case_id}.yaml"
    path.write_text(text)
    load_scenario(path)  # the schema accepts it
    out = tmp_path / "deep" / "out"
    rc, err = _run(capsys, ["render", str(path), "--out", str(out)])
    assert rc == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and str(path) in lines[0], err
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]  # not even the parent "deep"


def test_missing_file(tmp_path, capsys):
    path = tmp_path / "nope.yaml"
    out = tmp_path / "out"
    rc, err = _run(capsys, ["render", str(path), "--out", str(out)])
    assert rc == 2
    assert len(err.strip().splitlines()) == 1
    assert str(path) in err and "no such file" in err
    assert not out.exists()


def test_bad_scenario_leaves_previous_run_untouched(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "ground_truth.jsonl").write_text("old\n")
    path = tmp_path / "s.yaml"
    path.write_text("name: x\nfps: 0\n")
    rc, err = _run(capsys, ["render", str(path), "--out", str(out)])
    assert rc == 2 and "fps" in err
    assert sorted(p.name for p in out.iterdir()) == ["ground_truth.jsonl"]
    assert (out / "ground_truth.jsonl").read_text() == "old\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out", "s.yaml"]


@pytest.mark.parametrize("frames", ["0", "-3", "151"])  # the default scenario has 10 s * 15 fps = 150
def test_frames_must_be_positive(tmp_path, capsys, frames):
    path = tmp_path / "s.yaml"
    path.write_text("name: x\n")
    out = tmp_path / "out"
    rc, err = _run(capsys, ["render", str(path), "--out", str(out), "--frames", frames])
    assert rc == 2
    assert "--frames" in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_valid_minimal_scenario_defaults():
    """The defaults documented in docs/scenarios.md hold (a guard against silent schema drift)."""
    from harness.world.scenario import parse_scenario

    s = parse_scenario({"name": "x"})
    assert (s.seed, s.duration_s, s.fps, s.n_frames) == (0, 10.0, 15.0, 150)
    assert (s.road.lanes, s.road.lane_width_m, s.ego.lane, s.ego.speed_mps) == (3, 4.0, 1, 25.0)
    assert (s.road.markings.stripe_length_m, s.road.markings.period_m) == (3.05, 12.19)
    assert (s.camera.width, s.camera.height, s.camera.hfov_deg, s.camera.height_m) == (640, 360, 70.0, 1.3)
    # the camera the scenario describes, against the pinhole formula f = (w/2)/tan(hfov/2)
    import math

    cam = s.camera.model()
    assert cam.fx == pytest.approx(320 / math.tan(math.radians(35)))
    assert cam.horizon_row == pytest.approx(179.5 - cam.fy * math.tan(math.radians(2.0)))


def _doc_default(cell: str):
    """A default cell of docs/scenarios.md as a Python value (None: not a value to compare)."""
    cell = cell.strip().replace("\u2212", "-").strip("`")
    if not cell or cell.startswith("**"):
        return None
    if cell in ("true", "false", "null"):
        return {"true": True, "false": False, "null": "null"}[cell]
    if cell.startswith("["):
        return [float(x) for x in cell.strip("[]").split(",") if x.strip()]
    try:
        return float(cell)
    except ValueError:
        return cell


def test_documented_defaults_table():
    """Every default in the field tables of docs/scenarios.md equals the schema's (docs and code agree)."""
    import re
    from pathlib import Path

    from harness.world.scenario import Street, parse_scenario

    s = parse_scenario({"name": "x", "vehicles": [{"name": "a", "distance_m": 10}]})
    sections = {"Top level": s, "`road`": s.road, "`traffic`": s.traffic, "`ego`": s.ego,
                "`vehicles`": s.vehicles[0], "`camera`": s.camera, "`render`": s.render, "`road.street`": Street()}
    text = (Path(__file__).resolve().parents[1] / "docs" / "scenarios.md").read_text(encoding="utf-8")
    target, checked = None, 0
    for line in text.splitlines():
        if line.startswith("## "):
            target = next((obj for key, obj in sections.items() if line[3:].startswith(key)), None)
            continue
        cells = [c.strip() for c in re.split(r"(?<!\\)\|", line.strip().strip("|"))] if line.startswith("| `") else []
        if target is None or len(cells) < 3 or cells[1] in ("mapping", "list"):
            continue
        names = re.findall(r"`([\w.]+)`", cells[0])
        defaults = [_doc_default(c) for c in cells[2].split(", ")] if len(names) > 1 else [_doc_default(cells[2])]
        for name, want in zip(names, defaults):
            if want is None:
                continue
            got = target
            for part in name.split("."):
                got = getattr(got, part)
            got = getattr(got, "value", got)
            if want == "null":
                assert got is None, name
            elif isinstance(want, list):
                assert list(got) == pytest.approx(want), name
            elif isinstance(want, float) and not isinstance(got, bool):
                assert got == pytest.approx(want), name
            else:
                assert got == want, name
            checked += 1
    assert checked >= 40  # the tables were found and read


def test_yaml_anchor_and_comment_friendly(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text(textwrap.dedent("""\
        # comment
        name: ok
        vehicles:
          - &car {name: a, distance_m: 10, behaviour: stationary}
          - {<<: *car, name: b, lane: -1}
        """))
    s = load_scenario(path)
    assert [v.name for v in s.vehicles] == ["a", "b"] and s.vehicles[1].lane == -1


def test_every_shipped_yaml_parses_and_every_shipped_scenario_loads():
    """Recursively: no shipped config has a duplicate key, every scenario has a valid (directory-safe) name."""
    from pathlib import Path

    from harness.scorecard.protocols import load_protocol
    from harness.sweep.spec import load_sweep_spec
    from monorarp.core.readers import read_yaml

    root = Path(__file__).resolve().parents[1] / "scenarios"
    kinds = {"scenario": 0, "sweep": 0, "protocol": 0}
    for path in sorted(root.rglob("*.yaml")):
        data = read_yaml(path, "config")
        if "suite" in data:
            load_protocol(path)
            kinds["protocol"] += 1
        elif {"variants", "scenarios"} & data.keys():
            load_sweep_spec(path)
            kinds["sweep"] += 1
        else:
            assert load_scenario(path).name == data["name"]
            kinds["scenario"] += 1
    assert min(kinds.values()) >= 3, kinds


@pytest.mark.parametrize("name", ["a", "highway_cruise", "_x", "v1.2+fog", "A-b"])
def test_plain_scenario_names_are_accepted(tmp_path, name):
    path = tmp_path / "s.yaml"
    path.write_text(f"name: '{name}'\n")
    assert load_scenario(path).name == name


def test_merged_keys_may_be_overridden_but_not_given_twice():
    from monorarp.core.errors import UserError
    from monorarp.core.readers import parse_yaml

    assert parse_yaml("a: &b {x: 1, y: 2}\nc: {<<: *b, x: 3}\n", "m.yaml")["c"] == {"x": 3, "y": 2}
    with pytest.raises(UserError, match=r"^m\.yaml: invalid YAML at line 4: duplicate key 'x' \(first at line 3\)$"):
        parse_yaml("a: &b {x: 1}\nc:\n  x: 3\n  x: 4\n", "m.yaml")
    with pytest.raises(UserError, match="duplicate key 'k'"):   # an alias used twice as a key
        parse_yaml("- &k k\n- {*k : 1, *k : 2}\n", "m.yaml")
