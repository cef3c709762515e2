"""Numba backend of :func:`monorarp.risk.monte_carlo.rollout.simulate`: one compiled loop per sample.

Same model, inputs and outputs as the numpy rollout, always in float64; agrees with it up to
floating-point rounding. Importing this module does not need numba: :data:`NUMBA_AVAILABLE`
says whether the backend can run. Sorting, shortcuts and compilation cache:
docs/monte_carlo_risk.md.
"""

from __future__ import annotations

import numpy as np

from monorarp.risk.monte_carlo.drivers import DriverParams
from monorarp.risk.monte_carlo.idm import MIN_GAP_M
from monorarp.risk.monte_carlo.rollout import MAX_VEHICLES, PHANTOM_X, RolloutConfig, RolloutResult, Scene

try:
    from numba import njit
    NUMBA_AVAILABLE = True
    NUMBA_IMPORT_ERROR = ""
except ImportError as exc:  # pragma: no cover - depends on the environment
    NUMBA_AVAILABLE = False
    NUMBA_IMPORT_ERROR = str(exc)

    def njit(*args, **kwargs):  # noqa: D103 - plain-Python stand-in so the module still imports
        return (lambda f: f) if not (len(args) == 1 and callable(args[0])) else args[0]


_JIT = dict(cache=True, fastmath=False, error_model="numpy", nogil=True)


@njit(**_JIT)
def _nmin(a: float, b: float) -> float:
    """``np.minimum`` of two scalars (NaN propagates)."""
    return a if (a < b or a != a) else b


@njit(**_JIT)
def _nmax(a: float, b: float) -> float:
    """``np.maximum`` of two scalars (NaN propagates)."""
    return a if (a > b or a != a) else b


@njit(**_JIT)
def _idm(v, a, afree, T, c, s0, dv, gap, floor_s_star):
    """IDM acceleration, in the numpy path's operation order (``afree = a (1 - (v/v0)^4)``, ``c = 1/(2 sqrt(ab))``)."""
    dyn = (dv * c + T) * v
    if floor_s_star and dyn < 0.0:
        dyn = 0.0
    dyn = (dyn + s0) / (gap if gap > MIN_GAP_M else MIN_GAP_M)
    return afree - (dyn * dyn) * a


@njit(**_JIT)
def _sort_order(order, x, n):
    """Insertion sort of ``order`` (a permutation of 0..n-1) by the key (x, index)."""
    for r in range(1, n):
        i = order[r]
        xi = x[i]
        q = r - 1
        while q >= 0:
            j = order[q]
            if x[j] > xi or (x[j] == xi and j > i):
                order[q + 1] = j
                q -= 1
            else:
                break
        order[q + 1] = i


@njit(**_JIT)
def _leaders(order, cur, tgt, n, lane_min, seen, lead_cur, lead_tgt, lead_l, lead_r, sides):
    """Leader (index, n = nobody) of each vehicle in its current and target lanes, and side lanes if ``sides``."""
    seen[:] = n
    for r in range(n - 1, -1, -1):
        i = order[r]
        sc = cur[i] - lane_min + 1
        st = tgt[i] - lane_min + 1
        lead_cur[i] = seen[sc]
        lead_tgt[i] = seen[st]
        if sides:
            lead_l[i] = seen[sc - 1]
            lead_r[i] = seen[sc + 1]
        seen[sc] = i
        seen[st] = i


@njit(**_JIT)
def _followers(order, cur, tgt, n, lane_min, seen, foll_l, foll_r, foll_o):
    """Follower (n = nobody) of every vehicle in the lanes left of, right of and at its current lane."""
    seen[:] = n
    for r in range(n):
        i = order[r]
        sc = cur[i] - lane_min + 1
        foll_l[i] = seen[sc - 1]
        foll_r[i] = seen[sc + 1]
        foll_o[i] = seen[sc]
        seen[sc] = i
        seen[tgt[i] - lane_min + 1] = i


@njit(**_JIT)
def _kernel(x0, y0, v0s, cur0, tgt0, hl_in, hx, hy, can_mobil,
            inv_v0_in, a_in, T_in, c_in, s0_in, p_in, th_in, bsafe_in,
            dt, n_steps, W, lane_min, lane_max, mobil_every, v_lat, min_speed, cooldown,
            accel_limit, decel_limit, floor_s_star, euler, near_miss, ego_cv, record,
            conflict_t, collision_t, lane_changes, rec_x, rec_y, rec_v):
    """Simulate every sample (rows of the (S, N) inputs); writes the (S, N) outputs and, if ``record``, (K+1, S, N).

    ``ego_cv``: the ego (vehicle 0) holds its speed and lateral position (acceleration 0, no lateral
    motion; the caller has already set its target lane to its current one and switched its MOBIL off).
    """
    S, n = x0.shape
    any_mobil = False
    for i in range(n):
        any_mobil = any_mobil or can_mobil[i]
    n_slots = lane_max - lane_min + 3
    # per-sample state; index n is the phantom (far ahead, speed 0, size 0, free term 0)
    x = np.empty(n + 1)
    v = np.empty(n + 1)
    hl = np.empty(n + 1)
    inv_v0 = np.empty(n + 1)
    front = np.empty(n + 1)
    rear = np.empty(n + 1)
    free = np.empty(n + 1)
    y = np.empty(n)
    vy = np.empty(n)
    tgt_y = np.empty(n)
    last = np.empty(n)
    acc = np.empty(n)
    acc_raw = np.empty(n)
    afree = np.empty(n)
    cur = np.empty(n, np.int64)
    tgt = np.empty(n, np.int64)
    order = np.empty(n, np.int64)
    lead_cur = np.empty(n, np.int64)
    lead_tgt = np.empty(n, np.int64)
    lead_l = np.empty(n, np.int64)
    lead_r = np.empty(n, np.int64)
    foll_l = np.empty(n, np.int64)
    foll_r = np.empty(n, np.int64)
    foll_o = np.empty(n, np.int64)
    decision = np.zeros(n, np.int64)
    seen = np.empty(n_slots, np.int64)
    for i in range(n):
        hl[i] = hl_in[i]
    hl[n] = 0.0
    reach = near_miss * (1.0 + 1e-9) + 1e-9   # contact-test pre-filter horizon (s), a hair over near_miss
    for s in range(S):
        for i in range(n):
            x[i] = x0[s, i]
            v[i] = v0s[s, i]
            y[i] = y0[s, i]
            cur[i] = cur0[s, i]
            tgt[i] = tgt0[s, i]
            tgt_y[i] = tgt[i] * W
            inv_v0[i] = inv_v0_in[s, i]
            last[i] = -np.inf
            order[i] = i
            conflict_t[s, i] = np.inf
            collision_t[s, i] = np.inf
            lane_changes[s, i] = 0
        x[n] = PHANTOM_X
        v[n] = 0.0
        inv_v0[n] = 0.0
        for k in range(n_steps + 1):
            t = k * dt
            for i in range(n):
                q = (tgt_y[i] - y[i]) * (1.0 / dt)
                vy[i] = -v_lat if q < -v_lat else (v_lat if q > v_lat else q)
            if ego_cv:
                vy[0] = 0.0
            # ---- conflicts with the ego at t_k (closed-form CV contact window of two rectangles)
            for i in range(1, n):
                if collision_t[s, i] != np.inf:   # first conflict and first collision both known
                    continue
                dxl = x[i] - x[0]
                rvx = v[i] - v[0]
                dyl = y[i] - y[0]
                rvy = vy[i] - vy[0]
                # cheap exact pre-filter: no contact possible within near_miss along x or y (with a rounding margin)
                if abs(dxl) - hx[i] > abs(rvx) * reach or abs(dyl) - hy[i] > abs(rvy) * reach:
                    continue
                ta = (-hx[i] - dxl) / rvx
                tb = (hx[i] - dxl) / rvx
                tc = (-hy[i] - dyl) / rvy
                td = (hy[i] - dyl) / rvy
                enter = _nmax(_nmin(ta, tb), _nmin(tc, td))
                leave = _nmin(_nmax(ta, tb), _nmax(tc, td))
                if enter < leave and leave > 0.0 and enter < near_miss:
                    if conflict_t[s, i] == np.inf:
                        conflict_t[s, i] = t + (enter if enter > 0.0 else 0.0)
                    if enter <= 0.0 and collision_t[s, i] == np.inf:
                        collision_t[s, i] = t
            if record:
                for i in range(n):
                    rec_x[k, s, i] = x[i]
                    rec_y[k, s, i] = y[i]
                    rec_v[k, s, i] = v[i]
            if k == n_steps:
                break

            mobil_now = k % mobil_every == 0
            if mobil_now:   # relink: finished lane changes, order along the road, leaders
                for i in range(n):
                    if tgt[i] != cur[i] and abs(y[i] - tgt_y[i]) < 1e-3 * W:
                        cur[i] = tgt[i]
                _sort_order(order, x, n)
                _leaders(order, cur, tgt, n, lane_min, seen, lead_cur, lead_tgt, lead_l, lead_r, any_mobil)
            # ---- IDM behind the current lane's leader and, while changing, the target lane's (the smaller)
            for i in range(n + 1):
                front[i] = x[i] + hl[i]
                rear[i] = x[i] - hl[i]
                r = v[i] if v[i] > 0.0 else 0.0
                r *= inv_v0[i]
                r *= r
                free[i] = r * r
            for i in range(n):
                if ego_cv and i == 0:   # no IDM for a constant-speed ego (it is never a MOBIL candidate)
                    acc_raw[0] = 0.0
                    acc[0] = 0.0
                    continue
                a = a_in[s, i]
                afree[i] = (1.0 - free[i]) * a
                l0 = lead_cur[i]
                l1 = lead_tgt[i]
                a0 = _idm(v[i], a, afree[i], T_in[s, i], c_in[s, i], s0_in[s, i], v[i] - v[l0],
                          rear[l0] - front[i], floor_s_star)
                acc_raw[i] = a0
                acc[i] = a0
                if l1 != l0:   # changing lane behind another leader
                    a1 = _idm(v[i], a, afree[i], T_in[s, i], c_in[s, i], s0_in[s, i], v[i] - v[l1],
                              rear[l1] - front[i], floor_s_star)
                    acc[i] = _nmin(a0, a1)
            if mobil_now and any_mobil:
                changed = _mobil(s, n, t, x, v, front, rear, free, afree, acc_raw, cur, tgt, last, order,
                                 lane_min, lane_max, seen, lead_cur, lead_l, lead_r, foll_l, foll_r, foll_o,
                                 can_mobil, a_in, T_in, c_in, s0_in, p_in, th_in, bsafe_in,
                                 min_speed, cooldown, floor_s_star, decision)
                if changed:
                    for i in range(n):
                        d = decision[i]
                        if d != 0:
                            tgt[i] += d
                            tgt_y[i] = tgt[i] * W
                            last[i] = t
                            lane_changes[s, i] += 1
                    _leaders(order, cur, tgt, n, lane_min, seen, lead_cur, lead_tgt, lead_l, lead_r, False)
            # ---- integrate
            for i in range(n):
                ai = acc[i]
                ai = -decel_limit if ai < -decel_limit else (accel_limit if ai > accel_limit else ai)
                if euler:
                    x[i] += v[i] * dt
                    v[i] += ai * dt
                else:
                    v_new = ai * dt + v[i]
                    if v_new < 0.0:   # stops inside the step: exact stopping distance v^2 / (2 |a|)
                        x[i] += v[i] * v[i] / (-2.0 * (ai if ai < -1e-12 else -1e-12))
                        v_new = 0.0
                    else:
                        x[i] += (v[i] + v_new) * (0.5 * dt)
                    v[i] = v_new
                y[i] += vy[i] * dt


@njit(**_JIT)
def _mobil_side(i, n, s, nl, f, v, front, rear, free, afree, acc_raw, old_term, a, T, c, s0,
                p_in, th_in, bsafe_in, floor_s_star):
    """MOBIL (gain, safe and gain >= threshold) of ``i`` moving between leader ``nl`` and follower ``f`` (n = nobody).

    Branch-free on purpose: returning early for unsafe changes measured ~35 % slower overall.
    """
    vi = v[i]
    a_after = _idm(vi, a, afree[i], T, c, s0, vi - v[nl], rear[nl] - front[i], floor_s_star)
    if f < n:
        af = (1.0 - free[f]) * a
        bs = _idm(v[f], a, af, T, c, s0, v[f] - vi, rear[i] - front[f], floor_s_star)
        bo = _idm(v[f], a, af, T, c, s0, v[f] - v[nl], rear[nl] - front[f], floor_s_star)
    else:
        bs = 0.0
        bo = 0.0
    gain = bs - bo
    gain += old_term
    gain *= p_in[s, i]
    gain += a_after
    gain -= acc_raw[i]
    return gain, (bs >= -bsafe_in[s, i] and gain >= th_in[s, i])


@njit(**_JIT)
def _mobil(s, n, t, x, v, front, rear, free, afree, acc_raw, cur, tgt, last, order,
           lane_min, lane_max, seen, lead_cur, lead_l, lead_r, foll_l, foll_r, foll_o,
           can_mobil, a_in, T_in, c_in, s0_in, p_in, th_in, bsafe_in,
           min_speed, cooldown, floor_s_star, decision):
    """MOBIL decisions of sample ``s`` into ``decision`` (-1 left, 0 stay, +1 right); True if any vehicle changes.

    All decisions see the lanes before any of them changes (as the numpy path).
    """
    found = False
    for i in range(n):
        decision[i] = 0
        if can_mobil[i] and tgt[i] == cur[i] and v[i] >= min_speed and t - last[i] >= cooldown:
            found = True
    if not found:
        return False
    _followers(order, cur, tgt, n, lane_min, seen, foll_l, foll_r, foll_o)
    changed = False
    for i in range(n):
        if not (can_mobil[i] and tgt[i] == cur[i] and v[i] >= min_speed and t - last[i] >= cooldown):
            continue
        a, T, c, s0 = a_in[s, i], T_in[s, i], c_in[s, i], s0_in[s, i]
        vi = v[i]
        # old follower (its current leader is i): behind i now, behind i's leader after
        fo = foll_o[i]
        if fo < n:
            af = (1.0 - free[fo]) * a
            bs_o = _idm(v[fo], a, af, T, c, s0, v[fo] - vi, rear[i] - front[fo], floor_s_star)
            lo = lead_cur[i]
            bo_o = _idm(v[fo], a, af, T, c, s0, v[fo] - v[lo], rear[lo] - front[fo], floor_s_star)
        else:
            bs_o = 0.0
            bo_o = 0.0
        old_term = bo_o - bs_o
        g0, ok0, g1, ok1 = 0.0, False, 0.0, False   # a side outside [lane_min, lane_max] decides nothing
        if cur[i] > lane_min:
            g0, ok0 = _mobil_side(i, n, s, lead_l[i], foll_l[i], v, front, rear, free, afree, acc_raw, old_term,
                                  a, T, c, s0, p_in, th_in, bsafe_in, floor_s_star)
        if cur[i] < lane_max:
            g1, ok1 = _mobil_side(i, n, s, lead_r[i], foll_r[i], v, front, rear, free, afree, acc_raw, old_term,
                                  a, T, c, s0, p_in, th_in, bsafe_in, floor_s_star)
        right = (g1 > g0 or not ok0) and ok1
        left = ok0 and not right
        if right:
            decision[i] = 1
            changed = True
        elif left:
            decision[i] = -1
            changed = True
    return changed


_DUMMY_REC = np.empty((1, 1, 1))


def simulate_numba(scene: Scene, params: DriverParams, cfg: RolloutConfig, record: bool = False) -> RolloutResult:
    """:func:`monorarp.risk.monte_carlo.rollout.simulate` with the compiled kernel (float64; needs numba)."""
    if not NUMBA_AVAILABLE:
        raise RuntimeError(f"numba backend unavailable: {NUMBA_IMPORT_ERROR}")
    s, n = scene.x.shape
    if n > MAX_VEHICLES:   # same limit as the numpy path, so both backends accept the same scenes
        raise ValueError(f"at most {MAX_VEHICLES} vehicles (ego included) per rollout, got {n}")
    if cfg.delta != 4.0:
        raise ValueError("the rollout implements delta = 4 only")
    W, dt, k_steps = cfg.lane_width_m, cfg.dt, cfg.n_steps
    f64 = lambda a: np.ascontiguousarray(a, dtype=np.float64)  # noqa: E731
    y = f64(scene.y)
    cur = np.clip(np.rint(y / W).astype(np.int64), cfg.lane_min, cfg.lane_max)
    tgt = np.clip(np.clip(np.asarray(scene.target_lane, dtype=np.int64), cfg.lane_min, cfg.lane_max),
                  cur - 1, cur + 1)
    length, width = f64(scene.length), f64(scene.width)
    hx, hy = (length + length[0]) / 2.0, (width + width[0]) / 2.0
    can_mobil = np.ascontiguousarray(np.broadcast_to(np.asarray(scene.mobil, bool), (n,))
                                     & (cfg.lane_max > cfg.lane_min))
    ego_cv = cfg.ego_model == "constant_speed"
    if ego_cv:   # the ego keeps its lane: no target lane of its own, no MOBIL (as the numpy path)
        tgt[:, 0] = cur[:, 0]
        can_mobil[0] = False
    a, b = f64(params.a), f64(params.b)
    c = 0.5 / np.sqrt(a * b)
    conflict_t, collision_t = np.empty((s, n)), np.empty((s, n))
    lane_changes = np.empty((s, n), dtype=np.int64)
    if record:
        rec = [np.empty((k_steps + 1, s, n)) for _ in range(3)]
    else:
        rec = [_DUMMY_REC] * 3
    _kernel(f64(scene.x), y, f64(scene.v), np.ascontiguousarray(cur), np.ascontiguousarray(tgt), length / 2.0,
            hx, hy, can_mobil, 1.0 / f64(params.v0), a, f64(params.T), c, f64(params.s0),
            f64(params.politeness), f64(params.threshold), f64(params.b_safe),
            float(dt), int(k_steps), float(W), int(cfg.lane_min), int(cfg.lane_max),
            int(max(1, int(round(cfg.mobil_interval_s / dt)))), float(W / cfg.lane_change_duration_s),
            float(cfg.min_lane_change_speed_mps), float(cfg.lane_change_cooldown_s),
            float(cfg.accel_limit_mps2), float(cfg.decel_limit_mps2), bool(cfg.floor_s_star),
            cfg.integrator == "euler", float(cfg.near_miss_ttc_s), ego_cv, bool(record),
            conflict_t, collision_t, lane_changes, *rec)
    out = RolloutResult(conflict_t, collision_t, lane_changes)
    if record:
        out.x, out.y, out.v = rec
    return out


def warm_up() -> None:
    """Compile the kernel (or load it from numba's cache) now, with a tiny 2-vehicle, 3-lane rollout."""
    scene = Scene(x=np.array([[0.0, 20.0]]), y=np.zeros((1, 2)), v=np.array([[25.0, 20.0]]),
                  target_lane=np.zeros((1, 2), dtype=np.int64), length=np.full(2, 4.5), width=np.full(2, 1.8),
                  mobil=np.ones(2, bool))
    params = DriverParams.uniform((1, 2), v0=30.0)
    simulate_numba(scene, params, RolloutConfig(dt=0.5, horizon_s=1.0, lane_min=-1, lane_max=1))
