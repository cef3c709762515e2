"""Batched IDM/MOBIL traffic rollouts on a straight multi-lane road, and their conflicts with the ego.

Road frame of a rollout: ``x`` along the road (m, ego's initial centre at 0), ``y`` across it
(m, + right, ego's lane centre at 0); state arrays ``(S, N)``: S rollouts x N vehicles, vehicle 0
the ego, at most ``MAX_VEHICLES`` (61). The steps (relink, IDM, integration, lateral motion), the
ego model and the conflict test: docs/monte_carlo_risk.md.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from monorarp.risk.monte_carlo.drivers import DriverParams
from monorarp.risk.monte_carlo.idm import MIN_GAP_M, mobil_safe

EGO_MODELS = ("idm", "constant_speed")


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
    ego_model: Literal["idm", "constant_speed"] = "idm"   # constant_speed: vehicle 0 holds speed and lane

    def __post_init__(self) -> None:
        if self.ego_model not in EGO_MODELS:
            raise ValueError(f"ego_model must be one of {EGO_MODELS}, got {self.ego_model!r}")
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
MAX_VEHICLES = 61    # ego included: an int64 lane bitmask holds the ranks 1..N and two sentinel bits


class _Order:
    """Vehicles sorted along the road, per sample, and lane-membership bitmasks over that order.

    Vehicle-major arrays: (N, S) per vehicle, (N+1, S) state with row N the phantom
    ("nobody": far ahead as a leader, masked out as a follower). Ranks 1..N follow x
    (stable sort: exact ties in x keep the vehicle-index order). Lane ``l`` of a sample is a
    bitmask with bit ``rank`` set for every vehicle occupying it (current or target lane) and
    the sentinel bits 0 and N+1 (the phantom behind / ahead of everybody). The leader of a
    vehicle in a lane is the lowest set bit above its rank; the follower the highest below,
    found as the lowest set bit of the mirrored mask (ranks N+1-rank). Lanes are addressed by
    *slots* ``(lane - lane_min + 1) * S + sample`` (:meth:`slot`); slots of lanes just outside
    [lane_min, lane_max] are empty lanes.
    """

    def __init__(self, x: np.ndarray, lane_min: int, lane_max: int):
        n, s = x.shape[0] - 1, x.shape[1]
        if n > MAX_VEHICLES:
            raise ValueError(f"at most {MAX_VEHICLES} vehicles (ego included) per rollout, got {n}")
        self.n, self.s, self.lane_min = n, s, lane_min
        self.cols = np.arange(s)
        order = np.argsort(x[:n], axis=0, kind="stable")
        state_idx = order * s + self.cols                          # sorted position -> flat state index
        rank = np.empty(n * s, dtype=np.int64)
        rank[state_idx.ravel()] = np.repeat(np.arange(1, n + 1), s)
        rank = rank.reshape(n, s)
        self.bit = np.left_shift(1, rank)
        self.bit_m = np.left_shift(1, (n + 1) - rank)
        self.above = -(self.bit << 1)                              # bits strictly above the rank
        self.above_m = -(self.bit_m << 1)
        phantom = n * s + self.cols
        self.pos_to_state = np.concatenate([phantom, state_idx.ravel(), phantom])
        self.n_slots = (lane_max - lane_min + 3) * s
        self.sentinel = 1 | (1 << (n + 1))

    def slot(self, lane: np.ndarray) -> np.ndarray:
        """Slot of lane ``lane`` (N, S) in every sample."""
        return (lane - (self.lane_min - 1)) * self.s + self.cols

    def set_lanes(self, slot_cur: np.ndarray, slot_tgt: np.ndarray, changing: np.ndarray) -> None:
        """Lane bitmasks from the slots of the current / target lanes (N, S); ``changing``: tgt != cur."""
        self._fwd = np.full(self.n_slots, self.sentinel, dtype=np.int64)
        self._mir = self._fwd.copy()
        np.add.at(self._fwd, slot_cur.ravel(), self.bit.ravel())      # ranks are distinct: add = or
        np.add.at(self._mir, slot_cur.ravel(), self.bit_m.ravel())
        self.add(slot_tgt, changing)

    def add(self, slot_tgt: np.ndarray, where: np.ndarray) -> None:
        """Mark the vehicles ``where`` (N, S) as also occupying their target lane (slot ``slot_tgt``)."""
        idx = slot_tgt[where]
        np.add.at(self._fwd, idx, self.bit[where])
        np.add.at(self._mir, idx, self.bit_m[where])

    def leaders(self, slot: np.ndarray) -> np.ndarray:
        """Flat state index of the first occupant of lane ``slot`` (.., N, S) ahead of each vehicle."""
        hi = np.take(self._fwd, slot)
        hi &= self.above
        low = np.negative(hi)
        low &= hi
        low -= 1
        pos = np.bitwise_count(low).astype(np.int64)
        pos *= self.s
        pos += self.cols
        return np.take(self.pos_to_state, pos)

    def followers(self, slot: np.ndarray) -> np.ndarray:
        """Flat state index of the last occupant of lane ``slot`` (.., N, S) behind each vehicle."""
        hi = np.take(self._mir, slot)
        hi &= self.above_m
        low = np.negative(hi)
        low &= hi
        low -= 1
        pos = np.bitwise_count(low).astype(np.int64)
        pos *= -self.s
        pos += (self.n + 1) * self.s + self.cols
        return np.take(self.pos_to_state, pos)


class _Zeros:
    """Cached read-only zero arrays: ``np.maximum(a, zeros)`` is ~3x faster than with a scalar."""

    def __init__(self, dtype: np.dtype):
        self.dtype, self._cache = dtype, {}

    def __call__(self, shape: tuple, value: float = 0.0) -> np.ndarray:
        key = (shape, value)
        z = self._cache.get(key)
        if z is None:
            z = self._cache[key] = np.full(shape, value, dtype=self.dtype)
            z.flags.writeable = False
        return z


def _idm(v, a, afree, T, c, s0, dv, gap, floor_s_star: bool, zeros: _Zeros) -> np.ndarray:
    """IDM with precomputed ``afree = a (1 - (v/v0)^4)`` and ``c = 1 / (2 sqrt(a b))`` (see :mod:`idm`)."""
    dyn = dv * c
    dyn += T
    dyn *= v
    if floor_s_star:
        np.maximum(dyn, zeros(dyn.shape), out=dyn)
    dyn += s0
    dyn /= np.maximum(gap, zeros(gap.shape, MIN_GAP_M), out=gap)
    dyn *= dyn
    dyn *= a
    return np.subtract(afree, dyn, out=dyn)


def _pad(a: np.ndarray, value: float, dtype=float) -> np.ndarray:
    """(S, N) -> vehicle-major (N+1, S) with a phantom row ``value``."""
    a = np.asarray(a, dtype=dtype)
    return np.concatenate([a.T, np.full((1, a.shape[0]), value, dtype=dtype)])


# Largest (S, 2N) block simulated at once (rollouts are independent, so chunking does not change results).
# Keeps the temporaries of a step cache-sized; measured: 500 x 11 in one block is fastest.
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


class _Drivers:
    """Vehicle-major driver parameters in the state dtype: (N, S), ``inv_v0`` (N+1, S) with the phantom's 0."""

    def __init__(self, params: DriverParams, f: np.dtype):
        g = lambda k: np.ascontiguousarray(np.asarray(getattr(params, k), dtype=float).T)  # noqa: E731
        self.inv_v0 = _pad(1.0 / np.asarray(params.v0, dtype=float), 0.0, f)
        self.a, self.T, self.s0 = g("a").astype(f), g("T").astype(f), g("s0").astype(f)
        self.c = (0.5 / np.sqrt(g("a") * g("b"))).astype(f)
        self.p, self.th, self.b_safe = g("politeness").astype(f), g("threshold").astype(f), g("b_safe").astype(f)

    def free(self, v: np.ndarray) -> np.ndarray:
        """(v / v0)^4 of every row of ``v`` (N+1, S); speeds below 0 count as 0."""
        r = np.maximum(v, 0.0)
        r *= self.inv_v0
        r *= r
        r *= r
        return r


def _simulate(scene: Scene, params: DriverParams, cfg: RolloutConfig, record: bool) -> RolloutResult:
    s, n = scene.x.shape
    dt, W = cfg.dt, cfg.lane_width_m
    k_steps = cfg.n_steps
    mobil_every = max(1, int(round(cfg.mobil_interval_s / dt)))
    if cfg.delta != 4.0:
        raise ValueError("the rollout implements delta = 4 only")

    # vehicle-major state: x, v (N+1, S) with the phantom in row N; y (N, S)
    f = np.dtype(cfg.dtype)
    zeros = _Zeros(f)
    x = _pad(scene.x, PHANTOM_X, f)
    v = _pad(scene.v, 0.0, f)
    y = np.ascontiguousarray(np.asarray(scene.y, dtype=f).T)
    xn, vn = x[:n], v[:n]
    hl = np.concatenate([scene.length / 2.0, [0.0]]).astype(f)[:, None]     # half lengths (N+1, 1)
    D = _Drivers(params, f)
    cur = np.clip(np.rint(y / W).astype(np.int64), cfg.lane_min, cfg.lane_max)
    tgt = np.clip(np.clip(np.asarray(scene.target_lane, dtype=np.int64).T, cfg.lane_min, cfg.lane_max),
                  cur - 1, cur + 1)
    ego_cv = cfg.ego_model == "constant_speed"
    mobil = np.asarray(scene.mobil, bool)
    if ego_cv:   # the ego keeps its lane: no target lane of its own, no MOBIL
        tgt[0] = cur[0]
        mobil = mobil.copy()
        mobil[0] = False
    tgt_y = (tgt * W).astype(f)
    last_change = np.full((n, s), -np.inf)
    lane_changes = np.zeros((n, s), dtype=int)
    can_mobil = np.broadcast_to(mobil[:, None], (n, s)) & (cfg.lane_max > cfg.lane_min)
    any_mobil = bool(can_mobil.any())
    v_lat = W / cfg.lane_change_duration_s

    # conflict geometry against the ego (row 0) for rows 1..N-1
    hx = ((scene.length[1:] + scene.length[0]) / 2.0).astype(f)[:, None]
    hy = ((scene.width[1:] + scene.width[0]) / 2.0).astype(f)[:, None]
    conflict_t = np.full((n - 1, s), np.inf)
    collision_t = np.full((n - 1, s), np.inf)
    rec = [] if record else None

    order = lead = None
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for k in range(k_steps + 1):
            t = k * dt
            vy = np.subtract(tgt_y, y)
            vy *= 1.0 / dt
            np.clip(vy, -v_lat, v_lat, out=vy)
            if ego_cv:
                vy[0] = 0.0
            # ---- conflicts with the ego at t_k: closed-form constant-velocity contact window of two rectangles
            if n > 1:
                _conflicts(t, x[1:n] - x[0], v[1:n] - v[0], y[1:] - y[0], vy[1:] - vy[0], hx, hy,
                           cfg.near_miss_ttc_s, conflict_t, collision_t)
            if record:
                rec.append((xn.T.copy(), y.T.copy(), vn.T.copy()))
            if k == k_steps:
                break

            mobil_now = k % mobil_every == 0
            if mobil_now:   # lane membership (lane changes that reached their lane end) and a fresh x order
                changing = tgt != cur
                arrived = changing & (np.abs(y - tgt_y) < 1e-3 * W)
                if arrived.any():
                    cur = np.where(arrived, tgt, cur)
                    changing &= ~arrived
                order = _Order(x, cfg.lane_min, cfg.lane_max)
                slot_cur, slot_tgt = order.slot(cur), order.slot(tgt)
                order.set_lanes(slot_cur, slot_tgt, changing)
                if any_mobil:   # leaders in the lanes left, own, right; the target lane's is one of them
                    lead3 = order.leaders(np.stack([slot_cur - s, slot_cur, slot_cur + s]))
                    lead = np.stack([lead3[1], np.take(lead3, (tgt - cur + 1) * (n * s) + _cell_index(n, s))])
                else:
                    lead = order.leaders(np.stack([slot_cur, slot_tgt]))
            # ---- IDM behind the leader in the current lane and, while changing, the target lane (take the smaller)
            front, rear = x + hl, x - hl
            rear_l, v_l = np.take(rear, lead), np.take(v, lead)                 # (2, N, S)
            free = D.free(v)
            afree = 1.0 - free[:n]
            afree *= D.a
            acc2 = _idm(vn, D.a, afree, D.T, D.c, D.s0, vn - v_l, rear_l - front[:n], cfg.floor_s_star, zeros)
            acc_raw = acc2[0]
            acc = np.minimum(acc2[0], acc2[1])
            if mobil_now and any_mobil:
                cand = can_mobil & ~changing & (vn >= cfg.min_lane_change_speed_mps)
                cand &= t - last_change >= cfg.lane_change_cooldown_s
                ok, gain = _mobil(cfg, order, x, v, front, rear, free, D, acc_raw, afree, lead3, lead[0],
                                  slot_cur, cur, cand, zeros)
                d = _choose(ok, gain)
                change = d != 0
                if change.any():
                    tgt = tgt + d
                    tgt_y = (tgt * W).astype(f)
                    last_change[change] = t
                    lane_changes += change
                    slot_tgt = order.slot(tgt)
                    order.add(slot_tgt, change)
                    lead = order.leaders(np.stack([slot_cur, slot_tgt]))
            if ego_cv:
                acc[0] = 0.0
            np.clip(acc, -cfg.decel_limit_mps2, cfg.accel_limit_mps2, out=acc)
            # ---- integrate
            if cfg.integrator == "euler":
                xn += vn * dt
                vn += acc * dt
            else:
                v_new = acc * dt
                v_new += vn
                stopping = v_new < 0.0
                np.maximum(v_new, zeros(v_new.shape), out=v_new)
                dx = vn + v_new
                dx *= 0.5 * dt
                if stopping.any():   # stops inside the step: exact stopping distance v^2 / (2 |a|)
                    np.copyto(dx, vn * vn / (-2.0 * np.minimum(acc, -1e-12)), where=stopping)
                xn += dx
                vn[...] = v_new
            vy *= dt
            y += vy
    out = RolloutResult(_to_sn(conflict_t, s), _to_sn(collision_t, s), np.ascontiguousarray(lane_changes.T))
    if record:
        out.x, out.y, out.v = (np.stack([r[i] for r in rec]) for i in range(3))
    return out


_CELLS: dict = {}


def _cell_index(n: int, s: int) -> np.ndarray:
    """arange(N*S) as (N, S), cached."""
    c = _CELLS.get((n, s))
    if c is None:
        c = _CELLS[(n, s)] = np.arange(n * s).reshape(n, s)
    return c


def _to_sn(a: np.ndarray, s: int) -> np.ndarray:
    """(N-1, S) rows of the non-ego vehicles -> (S, N) with the ego's column inf."""
    return np.ascontiguousarray(np.concatenate([np.full((1, s), np.inf), a]).T)


def _conflicts(t, dxl, rvx, dyl, rvy, hx, hy, horizon, conflict_t, collision_t) -> None:
    """Record first conflicts / collisions at time ``t``: CV contact windows of rectangles (relative states)."""
    ta = (-hx - dxl) / rvx
    tb = (hx - dxl) / rvx
    tc = (-hy - dyl) / rvy
    td = (hy - dyl) / rvy
    enter = np.maximum(np.minimum(ta, tb), np.minimum(tc, td))
    leave = np.minimum(np.maximum(ta, tb), np.maximum(tc, td))
    conflict = enter < leave
    conflict &= leave > 0
    conflict &= enter < horizon
    if conflict.any():
        new = conflict & (conflict_t == np.inf)
        np.copyto(conflict_t, t + np.maximum(enter, 0.0), where=new)
        np.copyto(collision_t, t, where=conflict & (enter <= 0) & (collision_t == np.inf))


def _mobil(cfg, order, x, v, front, rear, free, D, acc_self_now, afree_self, lead3, lead_own, slot_cur, cur, cand,
           zeros):
    """MOBIL for both side lanes of every vehicle: (ok, gain), each (2, N, S), [left, right].

    As in highway-env's ``IDMVehicle.mobil``, the changer evaluates each
    follower's acceleration with its own IDM parameters (a, b, T, s0) and the
    follower's own desired speed and state. ``lead3`` (3, N, S): flat state
    indices of the leaders in the lanes left, own, right; ``lead_own`` (N, S) the
    current leader; ``acc_self_now`` the changer's current IDM acceleration.
    """
    n, s = cur.shape
    fs = cfg.floor_s_star
    new_lead = lead3[0::2]                                                      # (2, N, S)
    foll = order.followers(np.stack([slot_cur - s, slot_cur + s, slot_cur]))    # new -, new +, old (3, N, S)
    has_foll = foll < n * s
    a, T, c, s0 = D.a, D.T, D.c, D.s0
    xr_nl, v_nl = np.take(rear, new_lead), np.take(v, new_lead)
    xf_f, v_f = np.take(front, foll), np.take(v, foll)
    afree_f = 1.0 - np.take(free, foll)
    afree_f *= a
    vn = v[:n]
    # self behind the new leader
    a_self_after = _idm(vn, a, afree_self, T, c, s0, vn - v_nl, xr_nl - front[:n], fs, zeros)
    # each follower (new -, new +, old) behind self, and behind its other leader (new -, new +, old leader)
    behind_self = _idm(v_f, a, afree_f, T, c, s0, v_f - vn, rear[:n] - xf_f, fs, zeros)
    other = np.concatenate([new_lead, lead_own[None]])
    behind_other = _idm(v_f, a, afree_f, T, c, s0, v_f - np.take(v, other), np.take(rear, other) - xf_f, fs, zeros)
    behind_self *= has_foll     # no follower: highway-env's acceleration(None) = 0
    behind_other *= has_foll
    # gain = self + p * (new follower: after - now + old follower: after - now)
    gain = behind_self[:2] - behind_other[:2]
    gain += behind_other[2] - behind_self[2]
    gain *= D.p
    gain += a_self_after
    gain -= acc_self_now
    ok = mobil_safe(behind_self[:2], D.b_safe)
    ok &= gain >= D.th
    ok &= cand
    ok[0] &= cur > cfg.lane_min
    ok[1] &= cur < cfg.lane_max
    return ok, gain


def _choose(ok: np.ndarray, gain: np.ndarray) -> np.ndarray:
    """(N, S) in {-1, 0, +1}: the qualifying side with the larger gain (left on a tie)."""
    right = gain[1] > gain[0]
    right |= ~ok[0]
    right &= ok[1]
    left = ok[0] & ~right
    return right.astype(np.int64) - left


def mobil_sides(scene: Scene, params: DriverParams, cfg: RolloutConfig) -> np.ndarray:
    """MOBIL's verdict on each side lane for every vehicle of the initial scene: (2, S, N) bool, [left, right].

    The rollout's own code path (order + lanes + one MOBIL evaluation at t = 0, no
    cooldown, speed >= ``min_lane_change_speed_mps``), for parity tests against
    highway-env's ``IDMVehicle.mobil``. Lanes outside [lane_min, lane_max] are False.
    """
    s, n = scene.x.shape
    W = cfg.lane_width_m
    f = np.dtype(cfg.dtype)
    zeros = _Zeros(f)
    x, v = _pad(scene.x, PHANTOM_X, f), _pad(scene.v, 0.0, f)
    hl = np.concatenate([scene.length / 2.0, [0.0]]).astype(f)[:, None]
    D = _Drivers(params, f)
    cur = np.clip(np.rint(np.asarray(scene.y).T / W).astype(np.int64), cfg.lane_min, cfg.lane_max)
    order = _Order(x, cfg.lane_min, cfg.lane_max)
    slot_cur = order.slot(cur)
    order.set_lanes(slot_cur, slot_cur, np.zeros((n, s), bool))
    lead3 = order.leaders(np.stack([slot_cur - s, slot_cur, slot_cur + s]))
    front, rear = x + hl, x - hl
    free = D.free(v)
    afree = D.a * (1.0 - free[:n])
    with np.errstate(over="ignore"):
        acc_now = _idm(v[:n], D.a, afree, D.T, D.c, D.s0, v[:n] - np.take(v, lead3[1]),
                       np.take(rear, lead3[1]) - front[:n], cfg.floor_s_star, zeros)
        cand = np.broadcast_to(np.asarray(scene.mobil, bool)[:, None], (n, s)) \
            & (v[:n] >= cfg.min_lane_change_speed_mps)
        ok, _ = _mobil(cfg, order, x, v, front, rear, free, D, acc_now, afree, lead3, lead3[1], slot_cur, cur,
                       cand, zeros)
    return ok.transpose(0, 2, 1)
