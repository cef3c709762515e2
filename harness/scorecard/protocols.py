"""Collision-warning test protocols: files under ``scenarios/fcw/`` -> one scenario per trial.

A protocol file (YAML, validated; unknown keys refused) names a suite and its tests.
Conflict tests (``kind: rear_end`` or ``cut_in``) put a vehicle named ``target`` in
the ego's path; the ego drives straight at constant speed and never brakes (the
driver does not react in these tests), and the run ends 0.3 s after contact.
``kind: pass_by`` is a lane change in front of the ego that is no conflict (a
faster vehicle cutting in): a warning there fails the trial. ``kind: nominal``
runs shipped traffic scenarios for the false-alarm rate (``scenarios`` + seeds).

Each trial is one scenario built from the test's parameters and the trial's
seed (``seed = 1000 * trial + k`` for the k-th parameter combination), varying
what the protocols allow to vary: the start distance (from ``start_ttc_s``), the
target's model (size) and the colours, and traffic in the other lanes
(constant-speed vehicles that never change lanes, so the test stays clean).

Units: speeds in km/h where a field name says ``_kmh`` (the protocols' own
grids), everything else SI.
"""

from __future__ import annotations

import copy
import math
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from harness.world.config_io import Seed, validate_config
from harness.world.scenario import ScenarioError, load_scenario_dict
from monorarp.core.errors import UserError
from monorarp.core.readers import read_yaml

KMH = 1 / 3.6
#: Target vehicle models (length, width) a trial draws from: compact, mid-size, estate, SUV, van.
TARGET_MODELS = ((4.2, 1.75), (4.5, 1.8), (4.7, 1.85), (4.9, 1.95), (5.2, 2.0))
END_ON_CONTACT_S = 0.3


class ProtocolError(UserError, ValueError):
    """A protocol file that cannot be read or is invalid (file, field, reason)."""


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


#: The fields (besides ``test`` and ``kind``) each kind of test uses; setting another one is refused, as it
#: would be ignored. A rear_end test uses ``start_ttc_s`` unless its target brakes, then ``gap_m``,
#: ``target_decel_mps2`` and ``brake_at_s`` instead.
_CONFLICT = {"ego_speed_kmh", "target_speed_kmh", "adjacent_traffic", "trials", "min_trials_passed", "duration_s"}
FIELDS_USED = {
    "rear_end": _CONFLICT | {"target_motion", "lateral_offset", "required_ttc_s", "start_ttc_s", "gap_m",
                             "target_decel_mps2", "brake_at_s"},
    "cut_in": _CONFLICT | {"gap_m", "cut_in_at_s", "required_ttc_s"},
    "pass_by": _CONFLICT | {"gap_m", "cut_in_at_s"},
    "nominal": {"scenarios", "seeds", "duration_s", "warmup_s"},
}
_BRAKING_ONLY = ("gap_m", "target_decel_mps2", "brake_at_s")
_WHY_UNUSED = {"warmup_s": "only a nominal test's traffic has a warm-up (a conflict's is timed from t = 0)",
               "required_ttc_s": "a pass_by test is no conflict (any warning fails it): it has no required TTC"}


class Test(_Model):
    """One test of a suite; list-valued fields expand into one run per combination and trial."""

    test: str = Field(pattern=r"^[A-Za-z0-9_\-]+$", max_length=40)
    kind: Literal["rear_end", "cut_in", "pass_by", "nominal"] = "rear_end"
    target_motion: Literal["stationary", "moving", "braking"] = "moving"
    ego_speed_kmh: list[float] = Field(default_factory=lambda: [72.36], min_length=1)
    target_speed_kmh: float = Field(0.0, ge=0, le=200)
    gap_m: list[float] = Field(default_factory=list)
    start_ttc_s: tuple[float, float] = (5.5, 7.0)
    target_decel_mps2: list[float] = Field(default_factory=lambda: [0.0])
    brake_at_s: float = Field(2.0, ge=0.5, le=30)
    cut_in_at_s: float = Field(2.0, ge=0.5, le=30)
    lateral_offset: list[float] = Field(default_factory=lambda: [0.0])
    adjacent_traffic: tuple[int, int] = (0, 4)
    required_ttc_s: float | None = Field(None, gt=0, le=10)
    trials: int | None = Field(None, ge=1, le=1000)
    min_trials_passed: int | None = Field(None, ge=1)
    scenarios: list[str] = Field(default_factory=list)
    seeds: list[Seed] = Field(default_factory=list)
    duration_s: float | None = Field(None, gt=0, le=3600)
    warmup_s: float = Field(0.0, ge=0, le=60)

    @model_validator(mode="after")
    def _consistent(self) -> "Test":
        for name in type(self).model_fields:
            if name in ("test", "kind") or name not in self.model_fields_set:
                continue
            if name not in FIELDS_USED[self.kind]:
                raise ValueError(f"{name}: {_WHY_UNUSED.get(name, f'a {self.kind} test does not use it')}")
            if (self.kind == "rear_end" and name in (*_BRAKING_ONLY, "start_ttc_s")
                    and (name in _BRAKING_ONLY) != (self.target_motion == "braking")):
                raise ValueError(f"{name}: a rear_end test with a {self.target_motion} target does not use it")
        for name in ("ego_speed_kmh", "gap_m", "target_decel_mps2", "lateral_offset", "seeds", "scenarios"):
            shown = [Path(v).stem if name == "scenarios" else _fmt(v) for v in getattr(self, name)]
            dup = next((v for v, k in zip(getattr(self, name), shown) if shown.count(k) > 1), None)
            if dup is not None:   # the values name the runs: two equal ones would give two runs one id
                raise ValueError(f"{name}: repeated value {dup!r} (values must differ in their first 6 digits, "
                                 "scenario files in their names)")
        if any(not (v > 0 and math.isfinite(v)) or v > 250 for v in self.ego_speed_kmh):
            raise ValueError("ego_speed_kmh: every ego speed must be > 0 and <= 250 km/h")
        if any(g <= 0 for g in self.gap_m):
            raise ValueError("gap_m: a gap <= 0 puts the target at or behind the ego's camera")
        if any(g > 300 for g in self.gap_m):
            raise ValueError("gap_m: gaps beyond 300 m are out of the camera's range")
        lo, hi = self.start_ttc_s
        if not 0 < lo <= hi <= 30:
            raise ValueError("start_ttc_s: must be [low, high] with 0 < low <= high <= 30")
        if any(abs(o) > 1.0 for o in self.lateral_offset):
            raise ValueError("lateral_offset: a fraction of the target's width, within [-1, 1]")
        if any(d < 0 or d > 12 for d in self.target_decel_mps2):
            raise ValueError("target_decel_mps2: within [0, 12] m/s^2")
        a, b = self.adjacent_traffic
        if not 0 <= a <= b <= 12:
            raise ValueError("adjacent_traffic: [low, high] counts with 0 <= low <= high <= 12")
        if self.kind == "nominal":
            if not self.scenarios or not self.seeds:
                raise ValueError("a nominal test needs scenarios and seeds")
            return self
        if self.warmup_s:
            raise ValueError("warmup_s: only a nominal test's traffic has a warm-up (a conflict's is timed from t = 0)")
        moving = self.target_motion in ("moving", "braking") or self.kind in ("cut_in", "pass_by")
        if moving and self.target_speed_kmh <= 0:
            raise ValueError(f"target_speed_kmh: a {self.kind} test with a {self.target_motion} target "
                             f"needs a target speed > 0")
        if self.kind == "rear_end" and self.target_motion == "stationary" and self.target_speed_kmh != 0:
            raise ValueError("target_speed_kmh: a stationary target has speed 0")
        if self.kind in ("rear_end", "cut_in") and self.target_motion != "braking":
            slow = [v for v in self.ego_speed_kmh if v <= self.target_speed_kmh]
            if slow:
                raise ValueError(f"ego_speed_kmh: {slow[0]:g} km/h does not close on a target at "
                                 f"{self.target_speed_kmh:g} km/h: no conflict")
        if self.kind == "pass_by" and any(v >= self.target_speed_kmh for v in self.ego_speed_kmh):
            raise ValueError("target_speed_kmh: a pass_by vehicle must be faster than the ego")
        if self.target_motion == "braking":
            if not self.gap_m:
                raise ValueError("gap_m: a braking-target test needs the gap at the start of braking")
            if any(d <= 0 for d in self.target_decel_mps2):
                raise ValueError("target_decel_mps2: a braking target needs a deceleration > 0")
        if self.kind in ("cut_in", "pass_by") and not self.gap_m:
            raise ValueError("gap_m: a cut-in needs the gap (camera to the target's rear) at the cut-in")
        if self.kind in ("rear_end", "cut_in") and self.required_ttc_s is None:
            raise ValueError("required_ttc_s: a conflict test needs the TTC the warning must come at")
        return self


class Protocol(_Model):
    suite: str = Field(pattern=r"^[A-Za-z0-9_\-]+$", max_length=40)
    description: str = ""
    trials: int = Field(1, ge=1, le=1000)
    min_trials_passed: int | None = Field(None, ge=1)
    fps: float = Field(15.0, ge=5, le=60)
    camera: dict = Field(default_factory=dict)
    tests: list[Test] = Field(min_length=1)

    @model_validator(mode="after")
    def _unique(self) -> "Protocol":
        names = [t.test for t in self.tests]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ValueError(f"tests: repeated test names {dup}")
        for i, t in enumerate(self.tests):
            trials = t.trials or self.trials
            need = t.min_trials_passed or self.min_trials_passed or trials
            if need > trials:
                raise ValueError(f"tests.{i}.min_trials_passed: {need} exceeds the {trials} trials")
        return self


def load_protocol(path: str | Path) -> Protocol:
    return validate_config(Protocol, read_yaml(path, "protocol", ProtocolError), path, ProtocolError, "protocol")


# ------------------------------------------------------------------ trials
class Trial(BaseModel):
    """One run of a test: its identity, the parameters shown in the scorecard, the scenario mapping."""

    suite: str
    test: str
    kind: str
    key: str                     # test + parameter combination, without the trial (groups trials)
    trial: int
    ego_speed_mps: float | None
    target_speed_mps: float | None
    params: dict
    required_ttc_s: float | None
    conflict: bool
    min_trials_passed: int
    trials: int
    scenario: dict
    scenario_file: str


def _fmt(v: float) -> str:
    return f"{v:g}".replace("-", "m").replace(".", "p")


def contact_time(gap_m: float, v_ego: float, v_target: float, decel: float, brake_at: float,
                 horizon_s: float = 60.0, dt: float = 0.01) -> float | None:
    """First time (s) the ego's camera-to-rear gap closes, 1-D kinematics (the target stops at 0)."""
    t, gap, v_t = 0.0, gap_m, v_target
    while t < horizon_s:
        a = -decel if (decel > 0 and t >= brake_at and v_t > 0) else 0.0
        v_new = max(0.0, v_t + a * dt)
        gap += ((v_t + v_new) / 2 - v_ego) * dt
        v_t, t = v_new, t + dt
        if gap <= 0:
            return t
    return None


def _adjacent(rng: np.random.Generator, n: int, v_ego: float, lanes: tuple[int, ...], avoid: list[tuple[int, float]]
              ) -> list[dict]:
    """``n`` constant-speed vehicles in the other lanes, spread 10-120 m ahead and up to 30 m behind."""
    out: list[dict] = []
    taken = list(avoid)
    lane_speed = {la: float(np.clip(v_ego + rng.uniform(-3.0, 3.0), 0.5, 60.0)) for la in lanes}  # no catch-ups
    for k in range(n * 5):
        if len(out) == n:
            break
        lane = int(rng.choice(lanes))
        d = float(rng.uniform(-30.0, 120.0))
        if any(lane == la and abs(d - dd) < 14.0 for la, dd in taken) or -9.0 < d < 6.0:
            continue
        taken.append((lane, d))
        out.append({"name": f"traffic_{len(out)}", "lane": lane, "distance_m": round(d, 2),
                    "speed_mps": round(lane_speed[lane], 3), "behaviour": "constant_speed"})
    return out


def _base(protocol: Protocol, name: str, seed: int) -> dict:
    return {"name": name, "seed": seed, "fps": protocol.fps, "end_on_contact_s": END_ON_CONTACT_S,
            "road": {"lanes": 3}, "traffic": {"vehicles_count": 0},
            "camera": dict(protocol.camera), "render": {"palette_seed": seed}}


def conflict_scenario(protocol: Protocol, t: Test, v_ego_kmh: float, gap: float | None, decel: float,
                      offset: float, trial: int, seed: int) -> tuple[dict, dict]:
    """(scenario mapping, shown parameters) of one rear-end / cut-in / pass-by trial."""
    rng = np.random.default_rng(seed)
    v_ego, v_tgt = v_ego_kmh * KMH, t.target_speed_kmh * KMH
    length, width = TARGET_MODELS[int(rng.integers(len(TARGET_MODELS)))]
    scn = _base(protocol, f"{protocol.suite}_{t.test}", seed)
    scn["ego"] = {"lane": 1, "speed_mps": round(v_ego, 4), "behaviour": "constant_speed"}
    target = {"name": "target", "lane": 0, "speed_mps": round(v_tgt, 4), "length_m": length, "width_m": width,
              "lateral_offset_m": round(offset * width, 3),
              "behaviour": "stationary" if t.target_motion == "stationary" and t.kind == "rear_end"
              else "constant_speed"}
    events: list[dict] = []
    shown = {"offset": offset, "target_model_m": [length, width]}
    if t.kind == "rear_end":
        if t.target_motion == "braking":
            start = float(gap)
            events.append({"type": "brake", "vehicle": "target", "at_s": t.brake_at_s,
                           "decel_mps2": decel, "until_speed_mps": 0.0})
            shown.update(gap_m=gap, decel_mps2=decel)
        else:
            start_ttc = float(rng.uniform(*t.start_ttc_s))
            start = max(4.0, min(150.0, start_ttc * (v_ego - v_tgt)))
            shown.update(start_gap_m=round(start, 2))
        target["distance_m"] = round(start, 3)
        tc = contact_time(start, v_ego, v_tgt, decel, t.brake_at_s)
    else:
        side = 1 if rng.random() < 0.5 else -1
        target.update(lane=side, lateral_offset_m=0.0, distance_m=float(gap))
        events.append({"type": "cut_in", "vehicle": "target", "at_s": t.cut_in_at_s, "gap_m": float(gap)})
        shown.update(gap_m=gap, side=side)
        tc = None if t.kind == "pass_by" else contact_time(gap, v_ego, v_tgt, 0.0, 0.0)
        if t.kind != "pass_by" and tc is None:   # closing too slowly: no contact within contact_time's 60 s
            raise ProtocolError(f"ego_speed_kmh: at {v_ego / KMH:g} km/h the ego does not reach a target at "
                                f"{v_tgt / KMH:g} km/h {gap:g} m ahead within 60 s of the cut-in: no conflict")
        tc = None if tc is None else t.cut_in_at_s + tc
    scn["vehicles"] = [target]
    scn["events"] = events
    lanes = tuple(la for la in (-1, 1) if not (t.kind != "rear_end" and la == target["lane"]))
    n_adj = int(rng.integers(t.adjacent_traffic[0], t.adjacent_traffic[1] + 1))
    scn["vehicles"] += _adjacent(rng, n_adj, v_ego, lanes, [(target["lane"], target["distance_m"])])
    scn["duration_s"] = round(t.duration_s or (min(60.0, tc + 1.0) if tc is not None else t.cut_in_at_s + 8.0), 3)
    return scn, shown


def expand_protocol(protocol: Protocol, source: str | Path, trials: int | None = None) -> list[Trial]:
    """Every trial of every test, in a deterministic order. ``trials`` overrides the file's counts (for a
    nominal test: the number of seeds, counting up from its first)."""
    source = Path(source)
    out: list[Trial] = []
    for ti, t in enumerate(protocol.tests):
        n = trials or t.trials or protocol.trials
        need = min(n, t.min_trials_passed or protocol.min_trials_passed or n)
        if t.kind == "nominal":
            seeds = t.seeds if trials is None else [t.seeds[0] + i for i in range(trials)]
            for file in t.scenarios:
                path = (source.parent / file)
                try:
                    base = load_scenario_dict(path)
                except ScenarioError as e:
                    raise ProtocolError(f"{source}: tests.{ti}.scenarios: {e}") from None
                for seed in seeds:
                    scn = copy.deepcopy(base)
                    scn["seed"] = seed
                    if t.duration_s:
                        scn["duration_s"] = t.duration_s
                    if t.warmup_s:
                        scn["traffic"] = {**scn.get("traffic", {}), "warmup_s": t.warmup_s}
                    if protocol.camera:
                        scn["camera"] = {**scn.get("camera", {}), **protocol.camera}
                    key = f"{t.test}__{Path(file).stem}"
                    out.append(Trial(suite=protocol.suite, test=t.test, kind=t.kind, key=key, trial=seed,
                                     ego_speed_mps=None, target_speed_mps=None, params={"scenario": file},
                                     required_ttc_s=None, conflict=False, min_trials_passed=1, trials=1,
                                     scenario=scn, scenario_file=str(path)))
            continue
        gaps = t.gap_m or [None]
        decels = t.target_decel_mps2 if t.target_motion == "braking" else [0.0]
        k = 0
        for v in t.ego_speed_kmh:
            for gap in gaps:
                for decel in decels:
                    for off in t.lateral_offset:
                        key = "__".join([t.test, f"v{_fmt(v)}"] + ([f"gap{_fmt(gap)}"] if gap is not None else [])
                                        + ([f"dec{_fmt(decel)}"] if decel else []) + [f"off{_fmt(off)}"])
                        for trial in range(n):
                            seed = 1000 * trial + k
                            try:
                                scn, shown = conflict_scenario(protocol, t, v, gap, decel, off, trial, seed)
                            except ProtocolError as e:   # names the field; add the file and the test
                                raise ProtocolError(f"{source}: tests.{ti}.{e}") from None
                            out.append(Trial(suite=protocol.suite, test=t.test, kind=t.kind, key=key, trial=trial,
                                             ego_speed_mps=v * KMH, target_speed_mps=t.target_speed_kmh * KMH,
                                             params=shown, required_ttc_s=t.required_ttc_s,
                                             conflict=t.kind in ("rear_end", "cut_in"), min_trials_passed=need,
                                             trials=n, scenario=scn, scenario_file=str(source)))
                        k += 1
    return out
