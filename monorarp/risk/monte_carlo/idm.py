"""Driver-model maths: IDM acceleration and the MOBIL lane-change rules, vectorised (pure numpy).

IDM (Treiber, Hennecke & Helbing 2000)::

    a_IDM = a * (1 - (v / v0)**delta - (s* / s)**2)
    s*    = s0 + v*T + v*dv / (2*sqrt(a*b))          (dv = v - v_leader, approach rate)

``s`` is the gap to the leader and ``s0`` the jam gap, both measured the same way
(this project: net bumper-to-bumper gap; highway-env: centre-to-centre distance
with ``s0 = DISTANCE_WANTED = 5 m + length``). Without a leader the interaction
term is 0 (pass ``gap = inf``). Treiber's book floors the dynamic part of ``s*``
at 0 (``floor_s_star``); highway-env does not, so the flag exists for parity.

MOBIL (Kesting, Treiber & Helbing 2007, symmetric rules, as in highway-env's
``IDMVehicle.mobil``): a driver changes lane when

* safety:    ``a_new_follower_after >= -b_safe``  and
* incentive: ``a_self_after - a_self_now
  + p * ((a_new_follower_after - a_new_follower_now) + (a_old_follower_after - a_old_follower_now))
  >= a_threshold``.

Units: m, s, m/s, m/s^2. All functions broadcast over arbitrary array shapes.
"""

from __future__ import annotations

import numpy as np

MIN_GAP_M = 1e-2  # gaps are floored here before dividing (as highway-env's ``utils.not_zero``)


def idm_acceleration(
    v: np.ndarray,
    v0: np.ndarray,
    gap: np.ndarray,
    dv: np.ndarray,
    a: np.ndarray,
    b: np.ndarray,
    T: np.ndarray,
    s0: np.ndarray,
    delta: float = 4.0,
    floor_s_star: bool = True,
) -> np.ndarray:
    """IDM acceleration (m/s^2) of a follower at speed ``v`` behind a leader ``gap`` m ahead.

    ``v0`` desired speed (m/s, > 0), ``dv = v - v_leader`` (m/s), ``a`` maximum
    acceleration, ``b`` comfortable deceleration (m/s^2, > 0), ``T`` time headway (s),
    ``s0`` jam gap (m). ``gap = inf`` means no leader. Speeds below 0 count as 0
    in the free-road term, as in highway-env.
    """
    v = np.asarray(v)
    ratio = np.maximum(v, 0.0) / v0
    if delta == 4.0:
        r2 = ratio * ratio
        free = r2 * r2
    else:
        free = np.power(ratio, delta)
    dyn = v * T + v * dv / (2.0 * np.sqrt(a * b))
    if floor_s_star:
        dyn = np.maximum(dyn, 0.0)
    q = (s0 + dyn) / np.maximum(gap, MIN_GAP_M)  # gap = inf -> 0
    return a * (1.0 - free - q * q)


def mobil_incentive(
    a_self_now: np.ndarray,
    a_self_after: np.ndarray,
    a_new_follower_now: np.ndarray,
    a_new_follower_after: np.ndarray,
    a_old_follower_now: np.ndarray,
    a_old_follower_after: np.ndarray,
    politeness: np.ndarray,
) -> np.ndarray:
    """MOBIL's acceleration gain (m/s^2) of a lane change; missing followers contribute 0 - 0."""
    return (a_self_after - a_self_now) + politeness * (
        (a_new_follower_after - a_new_follower_now) + (a_old_follower_after - a_old_follower_now)
    )


def mobil_safe(a_new_follower_after: np.ndarray, b_safe: np.ndarray) -> np.ndarray:
    """MOBIL's safety criterion: the new follower need not brake harder than ``b_safe`` (m/s^2)."""
    return a_new_follower_after >= -b_safe


def mobil_decision(
    a_self_now, a_self_after, a_new_follower_now, a_new_follower_after,
    a_old_follower_now, a_old_follower_after, politeness, threshold, b_safe,
) -> np.ndarray:
    """True where MOBIL recommends the lane change (safe and gain >= ``threshold``)."""
    gain = mobil_incentive(a_self_now, a_self_after, a_new_follower_now, a_new_follower_after,
                           a_old_follower_now, a_old_follower_after, politeness)
    return mobil_safe(a_new_follower_after, b_safe) & (gain >= threshold)
