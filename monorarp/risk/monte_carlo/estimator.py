"""Monte Carlo risk estimator (paper section VI-B): IDM/MOBIL rollouts of the estimated scene.

Registered as ``("risk", "monte_carlo")``. Per frame: the estimated states (ego frame, m, m/s)
become a road scene; ``n_rollouts`` futures are simulated for ``horizon_s`` (s) with sampled
drivers and noisy initial states; the risk (a probability, or the paper's mean 1/TTC in 1/s)
comes from the ego's conflicts in those futures. Scores, per-vehicle TTC, ego model, ego-speed
sources, backends and determinism: docs/monte_carlo_risk.md.
"""

from __future__ import annotations

import inspect
import math
from dataclasses import replace
from typing import Any

import numpy as np

from monorarp.core.camera import CameraModel
from monorarp.risk.monte_carlo.config import BACKENDS, MonteCarloConfig, MonteCarloConfigError, monte_carlo_config
from monorarp.risk.monte_carlo.drivers import ROW_NV, ROW_NX, ROW_NY, DriverParams
from monorarp.risk.monte_carlo.rollout import MAX_VEHICLES, RolloutConfig, RolloutResult, Scene, simulate
from monorarp.risk.monte_carlo.scene import Geometry, lane_of, lane_range, road_positions
from monorarp.core.types import ObjectState, RiskEstimate

FALLBACK_EGO_SPEED_MPS = 25.0
#: A state outside these bounds (or not finite) is not simulated; its TTC is None. No vehicle a dashcam
#: detects is this far ahead, to the side or this fast, and such an estimate (a box at the horizon row)
#: would size the rollouts' lane tables, which grow with the lanes spanned, or overflow them.
MAX_RANGE_M = 1000.0
MAX_LATERAL_M = 100.0
MAX_SPEED_MPS = 150.0
_EGO_KEY = -1


def usable_state(s: ObjectState) -> bool:
    """Can ``s`` enter the rollouts? Finite and within the bounds above."""
    vals = (s.d_x, s.d_y, s.v_x, s.v_y)
    return (all(math.isfinite(v) for v in vals) and abs(s.d_y) <= MAX_RANGE_M and abs(s.d_x) <= MAX_LATERAL_M
            and abs(s.v_x) <= MAX_SPEED_MPS and abs(s.v_y) <= MAX_SPEED_MPS)


def resolve_backend(backend: str) -> str:
    """``"numba"`` or ``"numpy"`` for a requested backend (``"auto"``: numba when importable).

    numba is imported here, not with the package (~0.3-0.5 s), so only an estimator pays for it.
    """
    if backend not in BACKENDS:
        raise MonteCarloConfigError(f"risk backend must be one of {BACKENDS}, got {backend!r}")
    if backend == "numpy":
        return backend
    from monorarp.risk.monte_carlo import rollout_numba
    if backend == "auto":
        return "numba" if rollout_numba.NUMBA_AVAILABLE else "numpy"
    if backend == "numba" and not rollout_numba.NUMBA_AVAILABLE:
        raise MonteCarloConfigError(f"risk backend 'numba' requested but numba cannot be imported "
                                    f"({rollout_numba.NUMBA_IMPORT_ERROR}); use backend='numpy' or 'auto'")
    return backend


class MonteCarloRisk:
    """IDM/MOBIL Monte Carlo collision risk. ``assess(states, t, ego_speed=None) -> RiskEstimate``.

    Settings: :class:`~monorarp.risk.monte_carlo.config.MonteCarloConfig` (defaults, ranges, units),
    given as ``config`` and/or as keyword ``overrides`` of its fields (the names the registry's
    ``kwargs`` and a sweep variant's ``risk_kwargs`` use); a bad one raises
    :class:`~monorarp.risk.monte_carlo.config.MonteCarloConfigError` naming it. ``camera``: the run's
    camera, whose mounting offsets replace ``camera_forward_offset_m`` / ``camera_lateral_offset_m``.
    ``self.config`` is the settings in use, ``self.rollout_config`` the simulation's.

    ``dt`` defaults to 0.2 s: IDM/MOBIL are smooth at that step (Treiber &
    Kesting report ballistic IDM stable and accurate up to ~0.5 s), a 1 s
    near-miss window is sampled 5 times, no contact can be missed (each step's
    closed-form CV contact test covers the next 1 s), and it halves the cost
    of 0.1 s (50 steps for the 10 s horizon). ``backend`` picks the rollout
    implementation (module docstring); ``self.backend`` is the one in use.
    ``ego_model="constant_speed"`` keeps the ego at its speed and in its lane in
    every rollout (a non-reacting driver, as in FCW test protocols); the default
    ``"idm"`` lets it brake and change lane like the other drivers.
    """

    uses_camera = True   # the registry passes the run's camera
    uses_seed = True     # a sweep passes the run's seed
    uses_ego_speed = True   # its result depends on the ego speed it is given

    def __init__(self, camera: CameraModel | None = None, config: MonteCarloConfig | None = None,
                 **overrides: Any) -> None:
        cfg = monte_carlo_config(config, overrides)
        if camera is not None:  # a CameraModel: take its mounting offsets
            cfg = monte_carlo_config(cfg, {"camera_forward_offset_m": camera.forward_offset_m,
                                           "camera_lateral_offset_m": camera.lateral_offset_m})
        self.config = cfg
        self.backend = resolve_backend(cfg.backend)   # the one in use: "numba" or "numpy"
        self._simulate = simulate
        if self.backend == "numba":
            from monorarp.risk.monte_carlo import rollout_numba
            self._simulate = rollout_numba.simulate_numba
            if cfg.warm_up:
                rollout_numba.warm_up()
        self.n_rollouts = cfg.n_rollouts
        self.seed = cfg.seed
        self.score = cfg.score
        self.ego_speed_mps = cfg.ego_speed_mps
        self.lanes_left, self.lanes_right = cfg.lanes_left, cfg.lanes_right
        self.ego_model = cfg.ego_model
        self.ego_lane_changes = cfg.ego_lane_changes and cfg.ego_model == "idm"
        self.lateral_lookahead_s = cfg.lateral_lookahead_s
        self.geometry = Geometry(cfg.vehicle_length_m, cfg.vehicle_width_m, cfg.ego_length_m, cfg.ego_width_m,
                                 cfg.camera_forward_offset_m, cfg.camera_lateral_offset_m, cfg.lane_width_m)
        self.noise = cfg.noise
        self.drivers = cfg.drivers
        self.rollout_config = RolloutConfig(dt=cfg.dt, horizon_s=cfg.horizon_s, lane_width_m=cfg.lane_width_m,
                                            mobil_interval_s=cfg.mobil_interval_s,
                                            lane_change_duration_s=cfg.lane_change_duration_s,
                                            lane_change_cooldown_s=cfg.lane_change_cooldown_s,
                                            decel_limit_mps2=cfg.decel_limit_mps2,
                                            near_miss_ttc_s=cfg.near_miss_ttc_s, dtype=cfg.dtype,
                                            ego_model=cfg.ego_model)
        self._fed_ego_speed: float | None = None
        self._blocks: dict[int, np.ndarray] = {}
        self.ego_speed_source = "none"
        self.last_result: RolloutResult | None = None

    # ------------------------------------------------------------------ inputs
    def set_ego_speed(self, speed_mps: float | None) -> None:
        """Feed the ego speed (m/s), e.g. from the ego-speed estimator; ``None`` forgets it."""
        self._fed_ego_speed = None if speed_mps is None or not math.isfinite(speed_mps) else float(speed_mps)

    def _ego_speed(self, ego_speed: float | None) -> float:
        for value, source in ((ego_speed, "argument"), (self._fed_ego_speed, "fed"),
                              (self.ego_speed_mps, "configured")):
            if value is not None and math.isfinite(value) and value <= MAX_SPEED_MPS:
                self.ego_speed_source = source
                return max(float(value), 0.0)
        self.ego_speed_source = "fallback"
        return FALLBACK_EGO_SPEED_MPS

    def _block(self, key: int) -> np.ndarray:
        blk = self._blocks.get(key)
        if blk is None:
            rng = np.random.default_rng([self.seed, 0 if key == _EGO_KEY else 1, abs(key), key < 0])
            blk = self.drivers.draw_block(rng, self.n_rollouts)
            self._blocks[key] = blk
        return blk

    # ------------------------------------------------------------------- scene
    @staticmethod
    def simulated_ids(states: dict[int, ObjectState]) -> list[int]:
        """Track ids that enter the rollouts: all with a usable state (finite, within :data:`MAX_RANGE_M`,
        :data:`MAX_LATERAL_M`, :data:`MAX_SPEED_MPS`), or the ``MAX_VEHICLES - 1`` nearest (rollout limit)."""
        ids = sorted(i for i, s in states.items() if usable_state(s))
        if len(ids) < MAX_VEHICLES:
            return ids
        near = sorted(ids, key=lambda i: (math.hypot(states[i].d_x, states[i].d_y), i))
        return sorted(near[:MAX_VEHICLES - 1])

    def build(self, states: dict[int, ObjectState], ego_speed: float) -> tuple[Scene, DriverParams]:
        """The rollouts' initial scene and sampled drivers for ``states`` at ``ego_speed`` (m/s)."""
        ids = self.simulated_ids(states)
        geo, nz, S = self.geometry, self.noise, self.n_rollouts
        self._blocks = {k: v for k, v in self._blocks.items() if k in states or k == _EGO_KEY}
        blocks = np.stack([self._block(_EGO_KEY)] + [self._block(i) for i in ids], axis=-1)  # (K, S, N)
        st = np.array([[states[i].d_x, states[i].d_y, states[i].v_x, states[i].v_y] for i in ids],
                      dtype=float).reshape(-1, 4)
        d_x, d_y, v_x, v_y = st.T
        x_nom, y_nom = road_positions(d_x, d_y, geo)
        dist = np.hypot(x_nom, y_nom)
        v_ego = ego_speed + nz.ego_speed_mps * blocks[ROW_NV, :, :1]                          # (S, 1)
        if self.ego_model == "constant_speed":   # exactly the given speed: no ego noise (relative speeds keep theirs)
            v_ego = np.full((S, 1), ego_speed)
        x = x_nom + (nz.position_m + nz.position_rel * dist) * blocks[ROW_NX, :, 1:]
        y = y_nom + nz.lateral_m * blocks[ROW_NY, :, 1:]
        v = v_ego + v_y + (nz.speed_mps + nz.speed_rel * dist) * blocks[ROW_NV, :, 1:]
        n = len(ids) + 1
        x = np.concatenate([np.zeros((S, 1)), x], axis=1)
        y = np.concatenate([np.zeros((S, 1)), y], axis=1)
        v = np.maximum(np.concatenate([v_ego, v], axis=1), 0.0)   # no reversing / oncoming traffic
        target = lane_of(y + np.concatenate([[0.0], v_x]) * self.lateral_lookahead_s, geo.lane_width_m)
        nominal_lanes = np.concatenate([lane_of(y_nom, geo.lane_width_m),
                                        lane_of(y_nom + v_x * self.lateral_lookahead_s, geo.lane_width_m)])
        lo, hi = lane_range(nominal_lanes, self.lanes_left, self.lanes_right)
        self._lanes = (lo, hi)
        length = np.array([geo.ego_length_m] + [geo.vehicle_length_m] * (n - 1))
        width = np.array([geo.ego_width_m] + [geo.vehicle_width_m] * (n - 1))
        mobil = np.ones(n, dtype=bool)
        mobil[0] = self.ego_lane_changes
        scene = Scene(x=x, y=y, v=v, target_lane=target, length=length, width=width, mobil=mobil)
        return scene, DriverParams.from_blocks(blocks, v, self.drivers)

    # -------------------------------------------------------------------- risk
    def assess(self, states: dict[int, ObjectState], t: float, ego_speed: float | None = None) -> RiskEstimate:
        """Risk of the scene ``states`` (ego frame, relative velocities) at frame time ``t`` (s)."""
        v_e = self._ego_speed(ego_speed)
        if not states:
            self.last_result = None
            return RiskEstimate(risk=0.0, ttc={}, kind=self.score)
        ids = self.simulated_ids(states)
        scene, params = self.build(states, v_e)
        lo, hi = self._lanes
        res = self._simulate(scene, params, replace(self.rollout_config, lane_min=lo, lane_max=hi))
        self.last_result = res
        conflict = res.conflict_t[:, 1:]
        if self.score == "probability":
            risk = float(np.isfinite(conflict).any(axis=1).mean())
        else:
            t_hit = np.maximum(res.collision_t[:, 1:].min(axis=1), self.rollout_config.dt)
            risk = float(np.mean(1.0 / t_hit))       # 1 / inf = 0 for rollouts without a collision
        med = np.median(conflict, axis=0)
        ttc = {tid: None for tid in sorted(states)}
        ttc.update({tid: (float(m) if np.isfinite(m) else None) for tid, m in zip(ids, med)})
        return RiskEstimate(risk=risk, ttc=ttc, kind=self.score)


def _signature() -> inspect.Signature:
    """``MonteCarloRisk(camera=None, config=None, *, <every MonteCarloConfig field>=default)``: the keywords
    ``**overrides`` takes, shown by ``inspect.signature`` (and ``help``), which the registry reads."""
    P = inspect.Parameter
    params = [P("camera", P.POSITIONAL_OR_KEYWORD, default=None, annotation="CameraModel | None"),
              P("config", P.POSITIONAL_OR_KEYWORD, default=None, annotation="MonteCarloConfig | None")]
    params += [P(name, P.KEYWORD_ONLY, default=f.get_default(call_default_factory=True), annotation=f.annotation)
               for name, f in MonteCarloConfig.model_fields.items()]
    return inspect.Signature(params, return_annotation=None)


MonteCarloRisk.__signature__ = _signature()
