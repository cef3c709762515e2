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
    dtype: str = "float64"            # state dtype; "float32" is faster, float64 for parity checks

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


PHANTOM_X = 1.0e9    # position of the phantom "no leader" vehicle (m): its interaction term is ~1e-15


class _Links:
    """Leader/follower structure of one relink (per sample, per lane); indices into (S, N+1) rows.

    Column N of every state array is a phantom standing for "nobody": far ahead
    as a leader, masked out as a follower.
    """

    def __init__(self, cfg: RolloutConfig, x: np.ndarray, cur: np.ndarray, tgt: np.ndarray):
        s, n = cur.shape
        n_lanes = cfg.lane_max - cfg.lane_min + 1
        code0 = cur - cfg.lane_min
        code1 = np.where(tgt != cur, tgt - cfg.lane_min, n_lanes + np.arange(n))  # own lane = nobody else's
        code = np.concatenate([code0, code1], axis=1)                       # (S, 2N) lane entries
        xr = x[:, :n]
        key = code * SPAN + np.concatenate([xr, xr], axis=1)
        order = np.argsort(key, axis=1)
        vid = order % n
        code_s = np.take_along_axis(code, order, axis=1)
        same = code_s[:, 1:] == code_s[:, :-1]
        lead_s = np.full((s, 2 * n), n)
        lead_s[:, :-1] = np.where(same, vid[:, 1:], n)
        foll_s = np.full((s, 2 * n), n)
        foll_s[:, 1:] = np.where(same, vid[:, :-1], n)
        lead = np.empty_like(lead_s)
        np.put_along_axis(lead, order, lead_s, axis=1)
        foll = np.empty_like(foll_s)
        np.put_along_axis(foll, order, foll_s, axis=1)
        self.n = n
        self.row = (np.arange(s) * (n + 1))[:, None]      # flat offset of each sample's row in (S, N+1)
        self.leader = np.concatenate([lead[:, :n], np.full((s, 1), n)], axis=1)      # (S, N+1)
        self.follower = np.concatenate([foll[:, :n], np.full((s, 1), n)], axis=1)
        self.leader_flat = self.row + self.leader
        # vehicles changing lane and their target-lane leader (flat indices)
        chg_s, chg_i = np.nonzero(tgt != cur)
        self.chg_flat = chg_s * (n + 1) + chg_i
        self.chg_lead_flat = chg_s * (n + 1) + lead[:, n:][chg_s, chg_i]
        self._order, self._code_s, self._vid, self._key = order, code_s, vid, key
        self._n_codes = n_lanes + n
        self._flat = None

    def _build_search(self) -> None:
        s = self._order.shape[0]
        key_s = np.take_along_axis(self._key, self._order, axis=1)
        lo = np.full((s, 1), -SPAN)                         # below every key of the row
        hi = np.full((s, 1), (self._n_codes + 1) * SPAN)    # above every key of the row
        self._band = (self._n_codes + 3) * SPAN
        self._flat = (np.concatenate([lo, key_s, hi], axis=1) + (np.arange(s) * self._band)[:, None]).ravel()
        n = self.n
        self._vid_flat = np.concatenate([np.full((s, 1), n), self._vid, np.full((s, 1), n)], axis=1).ravel()
        self._code_flat = np.concatenate([np.full((s, 1), -1), self._code_s, np.full((s, 1), -1)], axis=1).ravel()

    def neighbours_in_lane(self, s_idx: np.ndarray, lane_code: np.ndarray, x: np.ndarray):
        """Leader (first at or ahead of ``x``) and follower (last behind) in lane ``lane_code`` of sample ``s_idx``.

        1-D query arrays; vehicle indices, ``N`` (the phantom) where there is none. Ties count as
        leader, as in highway-env. One ``searchsorted`` for all samples: rows live in disjoint key bands.
        """
        if self._flat is None:
            self._build_search()
        pos = np.searchsorted(self._flat, lane_code * SPAN + x + s_idx * self._band, side="left")
        lead, foll = self._vid_flat[pos], self._vid_flat[pos - 1]   # sentinels keep pos-1 in the row
        n = self.n
        return (np.where(self._code_flat[pos] == lane_code, lead, n),
                np.where(self._code_flat[pos - 1] == lane_code, foll, n))


def _pad(a: np.ndarray, value: float, dtype=float) -> np.ndarray:
    return np.concatenate([np.asarray(a, dtype=dtype), np.full((a.shape[0], 1), value, dtype=dtype)], axis=1)


# Largest (S, 2N) block simulated at once. numpy temporaries above glibc's 128 KiB mmap threshold
# are mapped and page-faulted afresh on every operation (measured: 10-25x slower per element), so
# the samples are simulated in chunks whose arrays stay below it; rollouts are independent.
_MAX_ELEMS = 12_000


def simulate(scene: Scene, params: DriverParams, cfg: RolloutConfig, record: bool = False) -> RolloutResult:
    """Roll every sample forward ``cfg.horizon_s`` and collect its conflicts with the ego (vehicle 0)."""
    s, n = scene.x.shape
    per = max(16, _MAX_ELEMS // (2 * (n + 1)))
    n_chunks = -(-s // per)
    if n_chunks == 1:
        return _simulate(scene, params, cfg, record)
    bounds = np.linspace(0, s, n_chunks + 1).round().astype(int)
    parts = []
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        sub = Scene(scene.x[lo:hi], scene.y[lo:hi], scene.v[lo:hi], scene.target_lane[lo:hi],
                    scene.length, scene.width, scene.mobil)
        sub_p = DriverParams(*(getattr(params, f)[lo:hi] for f in _PARAM_FIELDS))
        parts.append(_simulate(sub, sub_p, cfg, record))
    cat = lambda f, ax=0: None if getattr(parts[0], f) is None else np.concatenate(  # noqa: E731
        [getattr(p, f) for p in parts], axis=ax)
    return RolloutResult(cat("conflict_t"), cat("collision_t"), cat("lane_changes"),
                         cat("x", 1), cat("y", 1), cat("v", 1))


_PARAM_FIELDS = ("v0", "T", "s0", "a", "b", "politeness", "threshold", "b_safe")


def _simulate(scene: Scene, params: DriverParams, cfg: RolloutConfig, record: bool) -> RolloutResult:
    s, n = scene.x.shape
    dt, W = cfg.dt, cfg.lane_width_m
    k_steps = cfg.n_steps
    mobil_every = max(1, int(round(cfg.mobil_interval_s / dt)))

    # state, contiguous (S, N+1); column N is the phantom
    dt_ = np.dtype(cfg.dtype)
    x = _pad(scene.x, PHANTOM_X, dt_)
    v = _pad(scene.v, 0.0, dt_)
    y = _pad(scene.y, 0.0, dt_)
    hl = np.concatenate([scene.length / 2.0, [0.0]]).astype(dt_)     # half lengths (N+1,)
    P = {k: _pad(getattr(params, k), 1.0, dt_) for k in _PARAM_FIELDS}
    cur = np.clip(np.rint(scene.y / W).astype(int), cfg.lane_min, cfg.lane_max)
    tgt = np.clip(np.clip(scene.target_lane.astype(int), cfg.lane_min, cfg.lane_max), cur - 1, cur + 1)
    tgt_y = _pad(tgt * W, 0.0, dt_)
    last_change = np.full((s, n), -np.inf)
    lane_changes = np.zeros((s, n), dtype=int)
    can_mobil = np.broadcast_to(scene.mobil, (s, n)) & (cfg.lane_max > cfg.lane_min)
    v_lat = W / cfg.lane_change_duration_s

    # conflict geometry against the ego (column 0); the ego's own and the phantom's columns are masked
    hx = np.concatenate([(scene.length + scene.length[0]) / 2.0, [0.0]]).astype(dt_)
    hy = np.concatenate([(scene.width + scene.width[0]) / 2.0, [0.0]]).astype(dt_)
    conflict_t = np.full((s, n + 1), np.inf)
    collision_t = np.full((s, n + 1), np.inf)
    rec = [] if record else None

    def idm(vf, v0f, gap, dv, a, b, T, s0):
        return idm_acceleration(vf, v0f, gap, dv, a, b, T, s0, cfg.delta, cfg.floor_s_star)

    links = None
    for k in range(k_steps + 1):
        t = k * dt
        vy = np.clip((tgt_y - y) * (1.0 / dt), -v_lat, v_lat)
        # ---- conflicts with the ego at t_k: closed-form constant-velocity contact window of two rectangles
        with np.errstate(divide="ignore", invalid="ignore"):
            dxl, rvx = x - x[:, :1], v - v[:, :1]
            dyl, rvy = y - y[:, :1], vy - vy[:, :1]
            ta, tb = (-hx - dxl) / rvx, (hx - dxl) / rvx
            tc, td = (-hy - dyl) / rvy, (hy - dyl) / rvy
        enter = np.maximum(np.minimum(ta, tb), np.minimum(tc, td))
        leave = np.minimum(np.maximum(ta, tb), np.maximum(tc, td))
        conflict = (enter < leave) & (leave > 0) & (enter < cfg.near_miss_ttc_s)
        conflict[:, 0] = False
        if conflict.any():
            new = conflict & (conflict_t == np.inf)
            np.copyto(conflict_t, t + np.maximum(enter, 0.0), where=new)
            np.copyto(collision_t, t, where=new & (enter <= 0))
            np.copyto(collision_t, t, where=conflict & (enter <= 0) & (collision_t == np.inf))
        if record:
            rec.append((x[:, :n].copy(), y[:, :n].copy(), v[:, :n].copy()))
        if k == k_steps:
            break

        mobil_now = k % mobil_every == 0
        if mobil_now or links is None:   # membership: lane changes that reached their lane end
            arrived = (tgt != cur) & (np.abs(y[:, :n] - tgt * W) < 1e-3 * W)
            if links is None or arrived.any():
                cur = np.where(arrived, tgt, cur)
                links = _Links(cfg, x, cur, tgt)
        # ---- IDM behind the leader in the current lane (and the target lane while changing)
        gap = np.take(x, links.leader_flat) - x - (hl + hl[links.leader])
        acc_raw = idm(v, P["v0"], gap, v - np.take(v, links.leader_flat), P["a"], P["b"], P["T"], P["s0"])
        acc = acc_raw
        if links.chg_flat.size:
            cf, lf = links.chg_flat, links.chg_lead_flat
            gap1 = np.take(x, lf) - np.take(x, cf) - (np.take(hl, cf % (n + 1)) + np.take(hl, lf % (n + 1)))
            vc = np.take(v, cf)
            acc1 = idm(vc, np.take(P["v0"], cf), gap1, vc - np.take(v, lf),
                       *(np.take(P[q], cf) for q in ("a", "b", "T", "s0")))
            acc = acc_raw.copy()
            acc.flat[cf] = np.minimum(acc_raw.flat[cf], acc1)
        if mobil_now and can_mobil.any():
            cand = can_mobil & (tgt == cur) & (t - last_change >= cfg.lane_change_cooldown_s) \
                & (v[:, :n] >= cfg.min_lane_change_speed_mps)
            d = _mobil_decisions(cfg, links, x, v, hl, P, acc_raw, cur, cand)
            change = d != 0
            if change.any():
                tgt = np.where(change, cur + d, tgt)
                tgt_y[:, :n] = tgt * W
                last_change[change] = t
                lane_changes += change
                links = _Links(cfg, x, cur, tgt)
        np.clip(acc, -cfg.decel_limit_mps2, cfg.accel_limit_mps2, out=acc)
        # ---- integrate
        if cfg.integrator == "euler":
            x += v * dt
            v += acc * dt
        else:
            v_raw = v + acc * dt
            v_new = np.maximum(v_raw, 0.0)
            dx = (v + v_new) * (0.5 * dt)
            stopping = v_raw < 0.0
            if stopping.any():   # stops inside the step: exact stopping distance v^2 / (2 |a|)
                np.copyto(dx, v * v / (-2.0 * np.minimum(acc, -1e-12)), where=stopping)
            x += dx
            v = v_new
        y += vy * dt
        x[:, n] = PHANTOM_X
        v[:, n] = 0.0
    out = RolloutResult(conflict_t[:, :n], collision_t[:, :n], lane_changes)
    if record:
        out.x, out.y, out.v = (np.stack([r[i] for r in rec]) for i in range(3))
    return out


def _mobil_decisions(cfg, links, x, v, hl, P, acc_self_now, cur, cand, sides: bool = False):
    """MOBIL's choice for every candidate, (S, N) in {-1, 0, +1}; evaluated only for candidate (sample, vehicle, side).

    As in highway-env's ``IDMVehicle.mobil``, the changer evaluates each
    follower's acceleration with its own IDM parameters (a, b, T, s0) and the
    follower's own desired speed and state. When both sides qualify, the larger
    gain wins (highway-env takes the last side lane it checks).
    """
    s, n = cur.shape
    picks = []
    for d in (-1, 1):
        lane = cur + d
        si, vi = np.nonzero(cand & (lane >= cfg.lane_min) & (lane <= cfg.lane_max))
        picks.append((si, vi, np.full(si.size, d)))
    si, vi, di = (np.concatenate(z) for z in zip(*picks))
    if si.size == 0:
        return np.zeros((2, s, n), dtype=bool) if sides else np.zeros((s, n), dtype=int)
    me = si * (n + 1) + vi
    lane_code = cur[si, vi] + di - cfg.lane_min
    new_lead, new_foll = links.neighbours_in_lane(si, lane_code, x.flat[me])
    old_lead, old_foll = links.leader.flat[me], links.follower.flat[me]
    # rows: self behind new leader | new follower behind self | new follower behind new leader |
    #       old follower behind self | old follower behind old leader
    # (one row at a time: temporaries stay small, see _MAX_ELEMS)
    a, b, T, s0 = (np.take(P[q], me) for q in ("a", "b", "T", "s0"))
    row = si * (n + 1)
    acc = []
    for F, L in ((vi, new_lead), (new_foll, vi), (new_foll, new_lead), (old_foll, vi), (old_foll, old_lead)):
        Ff, Lf = F + row, L + row
        vf = np.take(v, Ff)
        gap = np.take(x, Lf) - np.take(x, Ff) - (np.take(hl, F) + np.take(hl, L))
        r = idm_acceleration(vf, np.take(P["v0"], Ff), gap, vf - np.take(v, Lf), a, b, T, s0,
                             cfg.delta, cfg.floor_s_star)
        r[F == n] = 0.0   # no follower: highway-env's acceleration(None) = 0
        acc.append(r)
    a_now = acc_self_now.flat[me]
    p, th, bs = (np.take(P[q], me) for q in ("politeness", "threshold", "b_safe"))
    ok = mobil_decision(a_now, acc[0], acc[2], acc[1], acc[3], acc[4], p, th, bs)
    gain = mobil_incentive(a_now, acc[0], acc[2], acc[1], acc[3], acc[4], p)
    best = np.full((2, s, n), -np.inf)
    best[(di + 1) // 2, si, vi] = np.where(ok, gain, -np.inf)
    if sides:
        return np.isfinite(best)
    right = best[1] > best[0]
    top = np.maximum(best[0], best[1])
    return np.where(np.isfinite(top), np.where(right, 1, -1), 0)


def mobil_sides(scene: Scene, params: DriverParams, cfg: RolloutConfig) -> np.ndarray:
    """MOBIL's verdict on each side lane for every vehicle of the initial scene: (2, S, N) bool, [left, right].

    The rollout's own code path (relink + one MOBIL evaluation at t = 0, no
    cooldown, speed >= ``min_lane_change_speed_mps``), for parity tests against
    highway-env's ``IDMVehicle.mobil``. Lanes outside [lane_min, lane_max] are False.
    """
    s, n = scene.x.shape
    W = cfg.lane_width_m
    x, v = _pad(scene.x, PHANTOM_X), _pad(scene.v, 0.0)
    hl = np.concatenate([scene.length / 2.0, [0.0]])
    P = {k: _pad(getattr(params, k), 1.0) for k in _PARAM_FIELDS}
    cur = np.clip(np.rint(scene.y / W).astype(int), cfg.lane_min, cfg.lane_max)
    links = _Links(cfg, x, cur, cur)
    gap = np.take(x, links.leader_flat) - x - (hl + hl[links.leader])
    acc_now = idm_acceleration(v, P["v0"], gap, v - np.take(v, links.leader_flat), P["a"], P["b"], P["T"], P["s0"],
                               cfg.delta, cfg.floor_s_star)
    cand = np.broadcast_to(scene.mobil, (s, n)) & (v[:, :n] >= cfg.min_lane_change_speed_mps)
    return _mobil_decisions(cfg, links, x, v, hl, P, acc_now, cur, cand, sides=True)
