"""Batched IDM/MOBIL traffic rollouts on a straight multi-lane road, and their conflicts with the ego.

Road frame of a rollout: ``x`` along the road (m, ego's initial centre at 0),
``y`` across it (m, + right, ego's lane centre at 0), lane ``l`` centred at
``y = l * lane_width``; vehicles drive in +x. State arrays are ``(S, N)``:
S rollouts (samples) x N vehicles, vehicle 0 is the ego. Everything is
vectorised across samples and vehicles; the only Python loop is over time steps.

Per step (``dt``):

1. every ``mobil_interval_s``: *relink* (lane membership -> leader/follower of
   every vehicle per lane, by sorting ``lane_code * SPAN + x`` per sample) and
   MOBIL decisions for vehicles that are not changing lane, are out of their
   cooldown and drive at least ``min_lane_change_speed_mps``;
2. IDM acceleration behind the leader in the current lane; a vehicle changing
   lane also follows the leader in its target lane and takes the smaller of the
   two (as highway-env's ``IDMVehicle.act``); clipped to
   ``[-decel_limit, accel_limit]`` (IDM alone can demand unbounded braking);
3. integration: ``ballistic`` (v_{k+1} = max(v_k + a dt, 0), x advanced by the
   mean speed, exact stop inside the step; Treiber & Kesting's scheme) or
   ``euler`` (x += v dt, then v += a dt, no clamp: highway-env's
   ``Vehicle.step`` on a straight lane, used for the parity test);
4. lateral: a lane change moves the vehicle towards its target lane centre at
   ``lane_width / lane_change_duration_s``; a vehicle off its lane centre drifts
   back at the same rate. While changing it occupies both lanes (both lanes'
   followers see it). Membership is updated at relink steps only.

Conflicts with the ego are checked at every step (``t_k = k dt``, k = 0..K):
the constant-velocity time to contact of the two axis-aligned rectangles from
the current positions and velocities (closed form, as :mod:`monorarp.ttc`). A
*conflict* is a contact within ``near_miss_ttc_s`` (a collision -- overlapping
rectangles -- is contact time 0). Per (rollout, vehicle) the result keeps the
first conflict's predicted contact time ``t_k + ttc_k`` and the first
collision time.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from monorarp.risk_mc.drivers import DriverParams
from monorarp.risk_mc.idm import idm_acceleration, mobil_decision, mobil_incentive

SPAN = 1.0e5          # lane code stride of the sort key; |x| stays far below this (m)


@dataclass(frozen=True)
class RolloutConfig:
    """Simulation settings (SI units)."""

    dt: float = 0.2
    horizon_s: float = 10.0
    lane_width_m: float = 3.7
    lane_min: int = 0                 # lowest allowed lane index (relative to the ego's lane 0)
    lane_max: int = 0                 # highest allowed lane index
    mobil_interval_s: float = 1.0     # MOBIL decision period (highway-env: LANE_CHANGE_DELAY = 1 s)
    lane_change_duration_s: float = 3.0
    lane_change_cooldown_s: float = 4.0   # at most one lane change per vehicle per this many s
    min_lane_change_speed_mps: float = 1.0
    accel_limit_mps2: float = 6.0     # highway-env's ACC_MAX
    decel_limit_mps2: float = 8.0     # tyre-road friction (~0.8 g)
    delta: float = 4.0
    floor_s_star: bool = True
    integrator: Literal["ballistic", "euler"] = "ballistic"
    near_miss_ttc_s: float = 1.0

    def __post_init__(self) -> None:
        if not (self.dt > 0 and self.horizon_s > 0 and self.lane_width_m > 0):
            raise ValueError("dt, horizon_s and lane_width_m must be positive")
        if self.lane_min > self.lane_max:
            raise ValueError(f"lane_min {self.lane_min} > lane_max {self.lane_max}")
        if self.integrator not in ("ballistic", "euler"):
            raise ValueError(f"unknown integrator {self.integrator!r}")

    @property
    def n_steps(self) -> int:
        return int(round(self.horizon_s / self.dt))


@dataclass
class Scene:
    """Initial state of every rollout: arrays (S, N), vehicle 0 = ego; sizes (N,)."""

    x: np.ndarray          # centre along the road (m)
    y: np.ndarray          # centre across the road (m, + right)
    v: np.ndarray          # speed along the road (m/s)
    target_lane: np.ndarray  # (S, N) int lane each vehicle is heading for
    length: np.ndarray     # (N,) m
    width: np.ndarray      # (N,) m
    mobil: np.ndarray      # (N,) bool: may this vehicle change lane


@dataclass
class RolloutResult:
    conflict_t: np.ndarray       # (S, N) predicted contact time (s) at the first conflict with the ego; inf if none
    collision_t: np.ndarray      # (S, N) first time (s) its rectangle overlaps the ego's; inf if none
    lane_changes: np.ndarray     # (S, N) number of lane changes started
    x: np.ndarray | None = None  # (K+1, S, N) trajectories when recorded
    y: np.ndarray | None = None
    v: np.ndarray | None = None


class _Links:
    """Leader/follower structure of one relink (per sample, per lane)."""

    def __init__(self, cfg: RolloutConfig, x_pad: np.ndarray, cur: np.ndarray, tgt: np.ndarray, n: int):
        s = x_pad.shape[0]
        phantom = n
        n_lanes = cfg.lane_max - cfg.lane_min + 1
        code0 = cur - cfg.lane_min
        code1 = np.where(tgt != cur, tgt - cfg.lane_min, n_lanes + np.arange(n))  # own lane = nobody else's
        code = np.concatenate([code0, code1], axis=1)                       # (S, 2N) entries
        x = x_pad[:, :n]
        key = code * SPAN + np.concatenate([x, x], axis=1)
        order = np.argsort(key, axis=1)
        vid = order % n
        code_s = np.take_along_axis(code, order, axis=1)
        same = code_s[:, 1:] == code_s[:, :-1]
        lead_s = np.full((s, 2 * n), phantom)
        lead_s[:, :-1] = np.where(same, vid[:, 1:], phantom)
        foll_s = np.full((s, 2 * n), phantom)
        foll_s[:, 1:] = np.where(same, vid[:, :-1], phantom)
        lead = np.empty_like(lead_s)
        np.put_along_axis(lead, order, lead_s, axis=1)
        foll = np.empty_like(foll_s)
        np.put_along_axis(foll, order, foll_s, axis=1)
        self.row = (np.arange(s) * (n + 1))[:, None]      # flat offset of each sample's row in (S, N+1)
        self.leader0 = lead[:, :n]
        self.follower0 = foll[:, :n]
        self.leader0_flat = self.row + self.leader0
        # vehicles changing lane: their target-lane leader, in flat form
        chg_s, chg_i = np.nonzero(tgt != cur)
        self.chg_flat = chg_s * (n + 1) + chg_i
        self.chg_lead_flat = chg_s * (n + 1) + lead[:, n:][chg_s, chg_i]
        self.chg_s, self.chg_i = chg_s, chg_i
        # sorted keys with a sentinel column on each side, for neighbour queries (built lazily)
        self._order, self._code_s, self._vid, self._key = order, code_s, vid, key
        self._n_codes = n_lanes + n
        self._flat = None

    def _build_search(self) -> None:
        s = self._order.shape[0]
        phantom = self.leader0.shape[1]
        key_s = np.take_along_axis(self._key, self._order, axis=1)
        lo = np.full((s, 1), -SPAN)                         # below every key of the row
        hi = np.full((s, 1), (self._n_codes + 1) * SPAN)    # above every key of the row
        band = (self._n_codes + 3) * SPAN
        self._row_key = (np.arange(s) * band)[:, None]
        self._flat = (np.concatenate([lo, key_s, hi], axis=1) + self._row_key).ravel()
        self._vid_pad = np.concatenate([np.full((s, 1), phantom), self._vid, np.full((s, 1), phantom)], axis=1)
        self._code_pad = np.concatenate([np.full((s, 1), -1), self._code_s, np.full((s, 1), -1)], axis=1)

    def neighbours_in_lane(self, lane_code: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Leader (first at or ahead of ``x``) and follower (last behind) in lane ``lane_code``, per (S, N).

        Vehicle indices; ``N`` (the phantom) where there is none. Ties count as leader, as in highway-env.
        One ``searchsorted`` over all samples: rows are offset into disjoint key bands.
        """
        if self._flat is None:
            self._build_search()
        s, e2 = self._vid_pad.shape
        q = lane_code * SPAN + x + self._row_key
        pos = np.searchsorted(self._flat, q.ravel(), side="left").reshape(q.shape)
        pos -= (np.arange(s) * e2)[:, None]                 # in [1, e2 - 1] thanks to the sentinels
        lead_idx = np.take_along_axis(self._vid_pad, pos, axis=1)
        lead_code = np.take_along_axis(self._code_pad, pos, axis=1)
        foll_idx = np.take_along_axis(self._vid_pad, pos - 1, axis=1)
        foll_code = np.take_along_axis(self._code_pad, pos - 1, axis=1)
        phantom = self.leader0.shape[1]
        return (np.where(lead_code == lane_code, lead_idx, phantom),
                np.where(foll_code == lane_code, foll_idx, phantom))


def simulate(scene: Scene, params: DriverParams, cfg: RolloutConfig, record: bool = False) -> RolloutResult:
    """Roll every sample forward ``cfg.horizon_s`` and collect its conflicts with the ego (vehicle 0)."""
    s, n = scene.x.shape
    dt, W = cfg.dt, cfg.lane_width_m
    k_steps = cfg.n_steps
    mobil_every = max(1, int(round(cfg.mobil_interval_s / dt)))

    # padded state (S, N+1): column N is a phantom leader at +inf (no leader)
    x_pad = np.concatenate([scene.x.astype(float), np.full((s, 1), np.inf)], axis=1)
    v_pad = np.concatenate([scene.v.astype(float), np.zeros((s, 1))], axis=1)
    half_len_pad = np.concatenate([scene.length / 2.0, [0.0]])
    x, v = x_pad[:, :n], v_pad[:, :n]
    y = scene.y.astype(float).copy()
    cur = np.clip(np.rint(y / W).astype(int), cfg.lane_min, cfg.lane_max)
    tgt = np.clip(scene.target_lane.astype(int), cfg.lane_min, cfg.lane_max)
    tgt = np.clip(tgt, cur - 1, cur + 1)
    v0, T, s0, a_max, b = params.v0, params.T, params.s0, params.a, params.b
    sqrt_ab2 = 2.0 * np.sqrt(a_max * b)
    last_change = np.full((s, n), -np.inf)
    lane_changes = np.zeros((s, n), dtype=int)
    can_mobil = np.broadcast_to(scene.mobil, (s, n))
    v_lat = W / cfg.lane_change_duration_s

    # ego-relative geometry for the conflict test (other vehicles 1..N-1)
    hx = (scene.length[1:] + scene.length[0]) / 2.0    # longitudinal half-extent sum
    hy = (scene.width[1:] + scene.width[0]) / 2.0
    conflict_t = np.full((s, n), np.inf)
    collision_t = np.full((s, n), np.inf)
    rec = [] if record else None

    def idm(vf, v0f, gap, dv, i_rows=None):
        if i_rows is None:
            return idm_acceleration(vf, v0f, gap, dv, a_max, b, T, s0, cfg.delta, cfg.floor_s_star)
        return idm_acceleration(vf, v0f, gap, dv, a_max[i_rows], b[i_rows], T[i_rows], s0[i_rows],
                                cfg.delta, cfg.floor_s_star)

    links = None
    for k in range(k_steps + 1):
        t = k * dt
        vy = np.clip((tgt * W - y) / dt, -v_lat, v_lat)
        # ---- conflicts with the ego at t_k (closed-form CV contact time of two rectangles)
        dxl = x[:, 1:] - x[:, :1]
        dyl = y[:, 1:] - y[:, :1]
        rvx = v[:, 1:] - v[:, :1]
        rvy = vy[:, 1:] - vy[:, :1]
        with np.errstate(divide="ignore", invalid="ignore"):
            ta, tb = (-hx - dxl) / rvx, (hx - dxl) / rvx
            tc, td = (-hy - dyl) / rvy, (hy - dyl) / rvy
        enter = np.maximum(np.minimum(ta, tb), np.minimum(tc, td))
        leave = np.minimum(np.maximum(ta, tb), np.maximum(tc, td))
        conflict = (enter < leave) & (leave > 0) & (enter < cfg.near_miss_ttc_s)
        if conflict.any():
            new = conflict & np.isinf(conflict_t[:, 1:])
            conflict_t[:, 1:] = np.where(new, t + np.maximum(enter, 0.0), conflict_t[:, 1:])
            hit = conflict & (enter <= 0) & np.isinf(collision_t[:, 1:])
            collision_t[:, 1:] = np.where(hit, t, collision_t[:, 1:])
        if record:
            rec.append((x.copy(), y.copy(), v.copy()))
        if k == k_steps:
            break

        # ---- relink + MOBIL
        if k % mobil_every == 0 or links is None:
            arrived = (tgt != cur) & (np.abs(y - tgt * W) < 1e-3 * W)
            cur = np.where(arrived, tgt, cur)
            links = _Links(cfg, x_pad, cur, tgt, n)
        # ---- IDM in the current lane (and the target lane while changing)
        xl = np.take(x_pad, links.leader0_flat)
        vl = np.take(v_pad, links.leader0_flat)
        gap = xl - x - (half_len_pad[:n] + half_len_pad[links.leader0])
        acc_raw = idm(v, v0, gap, v - vl)
        acc = acc_raw
        if links.chg_flat.size:
            cs, ci = links.chg_s, links.chg_i
            lf = links.chg_lead_flat
            gap1 = np.take(x_pad, lf) - x[cs, ci] - (half_len_pad[ci] + np.take(half_len_pad, lf % (n + 1)))
            acc1 = idm(v[cs, ci], v0[cs, ci], gap1, v[cs, ci] - np.take(v_pad, lf), (cs, ci))
            acc = acc_raw.copy()
            acc[cs, ci] = np.minimum(acc_raw[cs, ci], acc1)
        if k % mobil_every == 0 and cfg.lane_max > cfg.lane_min:
            _mobil_step(cfg, links, x_pad, v_pad, half_len_pad, params, sqrt_ab2, acc_raw, cur, tgt,
                        can_mobil & (tgt == cur) & (t - last_change >= cfg.lane_change_cooldown_s)
                        & (v >= cfg.min_lane_change_speed_mps),
                        n, t, last_change, lane_changes)
            if (tgt != cur).sum() != links.chg_flat.size:   # membership changed: relink now
                links = _Links(cfg, x_pad, cur, tgt, n)
        acc = np.clip(acc, -cfg.decel_limit_mps2, cfg.accel_limit_mps2)
        # ---- integrate
        if cfg.integrator == "euler":
            x += v * dt
            v += acc * dt
        else:
            v_raw = v + acc * dt
            v_new = np.maximum(v_raw, 0.0)
            stopping = v_raw < 0.0
            dx = (v + v_new) * (0.5 * dt)
            if stopping.any():
                with np.errstate(divide="ignore", invalid="ignore"):
                    dx = np.where(stopping, -v * v / (2.0 * acc), dx)
            x += dx
            v[:] = v_new
        y += vy * dt
    out = RolloutResult(conflict_t, collision_t, lane_changes)
    if record:
        out.x, out.y, out.v = (np.stack([r[i] for r in rec]) for i in range(3))
    return out


def _mobil_step(cfg, links, x_pad, v_pad, half_len_pad, params, sqrt_ab2, acc_self_now, cur, tgt,
                candidate, n, t, last_change, lane_changes) -> None:
    """MOBIL decisions for ``candidate`` vehicles; updates ``tgt``, ``last_change``, ``lane_changes`` in place.

    As in highway-env's ``IDMVehicle.mobil``, the changer evaluates every
    follower's acceleration with its own IDM parameters (a, b, T, s0) and the
    follower's own desired speed and state.
    """
    if not candidate.any():
        return
    s = x_pad.shape[0]
    x, v = x_pad[:, :n], v_pad[:, :n]
    row = links.row
    me = np.broadcast_to(np.arange(n), (s, n))
    v0_pad = np.concatenate([params.v0, np.ones((s, 1))], axis=1)
    gains, oks = [], []
    old_lead, old_foll = links.leader0, links.follower0
    for d in (-1, 1):
        lane = cur + d
        ok = candidate & (lane >= cfg.lane_min) & (lane <= cfg.lane_max)
        new_lead, new_foll = links.neighbours_in_lane(lane - cfg.lane_min, x)
        # rows: self behind new leader; new follower behind self; new follower behind new leader;
        #       old follower behind self; old follower behind old leader
        F = np.stack([me, new_foll, new_foll, old_foll, old_foll])
        L = np.stack([new_lead, me, new_lead, me, old_lead])
        Ff, Lf = F + row, L + row
        xf, vf, v0f = np.take(x_pad, Ff), np.take(v_pad, Ff), np.take(v0_pad, Ff)
        gap = np.take(x_pad, Lf) - xf - (half_len_pad[F] + half_len_pad[L])
        acc = idm_acceleration(vf, v0f, gap, vf - np.take(v_pad, Lf), params.a, params.b, params.T,
                               params.s0, cfg.delta, cfg.floor_s_star)
        acc = np.where(F == n, 0.0, acc)   # no follower: highway-env's acceleration(None) = 0
        decide = mobil_decision(acc_self_now, acc[0], acc[2], acc[1], acc[3], acc[4],
                                params.politeness, params.threshold, params.b_safe)
        gain = mobil_incentive(acc_self_now, acc[0], acc[2], acc[1], acc[3], acc[4], params.politeness)
        oks.append(ok & decide)
        gains.append(gain)
    go_left, go_right = oks
    right_better = gains[1] > gains[0]
    d = np.where(go_left & go_right, np.where(right_better, 1, -1), np.where(go_right, 1, np.where(go_left, -1, 0)))
    change = d != 0
    if change.any():
        tgt[:] = np.where(change, cur + d, tgt)
        last_change[:] = np.where(change, t, last_change)
        lane_changes += change


def mobil_wants(scene: Scene, params: DriverParams, cfg: RolloutConfig) -> np.ndarray:
    """MOBIL's choice for every vehicle in the initial scene, (S, N) in {-1, 0, +1} (lane index change).

    Uses the rollout's own code path (relink + one MOBIL step at t = 0, ignoring
    cooldown); exposed for parity tests against highway-env's ``IDMVehicle.mobil``.
    """
    s, n = scene.x.shape
    W = cfg.lane_width_m
    x_pad = np.concatenate([scene.x.astype(float), np.full((s, 1), np.inf)], axis=1)
    v_pad = np.concatenate([scene.v.astype(float), np.zeros((s, 1))], axis=1)
    half_len_pad = np.concatenate([scene.length / 2.0, [0.0]])
    cur = np.clip(np.rint(scene.y / W).astype(int), cfg.lane_min, cfg.lane_max)
    tgt = cur.copy()
    links = _Links(cfg, x_pad, cur, tgt, n)
    x, v = x_pad[:, :n], v_pad[:, :n]
    gap = np.take(x_pad, links.leader0_flat) - x - (half_len_pad[:n] + half_len_pad[links.leader0])
    acc_now = idm_acceleration(v, params.v0, gap, v - np.take(v_pad, links.leader0_flat), params.a, params.b,
                               params.T, params.s0, cfg.delta, cfg.floor_s_star)
    cand = np.broadcast_to(scene.mobil, (s, n)) & (v >= cfg.min_lane_change_speed_mps)
    _mobil_step(cfg, links, x_pad, v_pad, half_len_pad, params, 2.0 * np.sqrt(params.a * params.b), acc_now,
                cur, tgt, cand, n, 0.0, np.full((s, n), -np.inf), np.zeros((s, n), dtype=int))
    return tgt - cur
