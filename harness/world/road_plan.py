"""A road's horizontal alignment (plan): heading, curvature and centre line along the road (pure maths).

The simulation stays highway-env's straight 2-D road; the plan bends it. Road coordinates:
``x`` (m) the arc length along the reference line (highway-env's lane 0 centre, ``y = 0``), ``y``
(m) the lateral offset to the right. The reference line has heading ``theta(x)`` (rad, from +x
towards +y, i.e. + turns right) and curvature ``kappa(x) = dtheta/dx`` (1/m, + right). A road point
``(x, y)`` lies at the horizontal position ``P = C(x) + y n(x)`` with ``C`` the centre line and
``n = (-sin theta, cos theta)`` its right normal; points at offset ``y`` advance ``(1 - kappa y) dx``.

Before the first curve the line is highway-env's: ``C(x) = (x, 0)``, ``theta = 0``. Curve ``i``
starts at ``x_i`` with a clothoid (curvature linear in ``x``, as highways are built) of length
``T_i`` from 0 to ``k_i = +-1/R_i``, keeps ``k_i`` over ``L_i`` (a circular arc), then a clothoid
of ``T_i`` back to 0. With ``u = x - x_i``, curve ``i`` adds to ``theta``::

    k u^2 / (2T)                      0 <= u <= T
    k T / 2 + k (u - T)               T <= u <= T + L
    k T / 2 + k L + k (w - w^2/(2T))  w = u - T - L in [0, T]
    k (T + L)                         beyond

``C(x)`` integrates ``(cos theta, sin theta)`` by Simpson's rule on a grid of at most 1 m over the
curves (every breakpoint a node, so ``theta`` is smooth inside each panel) plus one Simpson step
from the last node; the tests bound its error against the closed forms.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

MIN_RADIUS_M = 50.0
"""Smallest radius (m) a scenario may give: tighter is an interchange loop, not a road segment
(highway design minimum ~250 m at 100 km/h, ~80 m at 50 km/h)."""
MAX_TURN_RAD = math.pi / 2
"""Largest heading (rad, either side) the road may reach: the road keeps advancing along +x, so it
never crosses itself."""
GRID_STEP_M = 1.0


@dataclass(frozen=True)
class RoadPlan:
    """Curves at absolute road ``x`` (m): ``starts``, ``transitions`` (clothoid lengths, m),
    ``lengths`` (arc lengths, m), ``curvatures`` (signed, 1/m, + right)."""

    starts: tuple[float, ...]
    transitions: tuple[float, ...]
    lengths: tuple[float, ...]
    curvatures: tuple[float, ...]
    _grid: tuple[np.ndarray, np.ndarray] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        xs = self.curved_x(GRID_STEP_M)     # every breakpoint is a node: theta is smooth inside each panel
        lo = xs[0]
        steps = _simpson(self, xs[:-1], xs[1:])
        cum = np.concatenate([np.zeros((1, 2)), np.cumsum(steps, axis=0)]) + [lo, 0.0]
        object.__setattr__(self, "_grid", (xs, cum))

    @classmethod
    def from_segments(cls, segments: Sequence, origin_x: float) -> "RoadPlan | None":
        """Plan of scenario curves (``start_m`` relative to ``origin_x``); None for a straight road."""
        segs = [s for s in (segments or []) if s.length_m + s.transition_m > 0]
        if not segs:
            return None
        return cls(tuple(origin_x + s.start_m for s in segs), tuple(float(s.transition_m) for s in segs),
                   tuple(float(s.length_m) for s in segs),
                   tuple((1.0 if s.direction == "right" else -1.0) / s.radius_m for s in segs))

    # ------------------------------------------------------------------ heading
    def _parts(self, x) -> tuple[np.ndarray, np.ndarray]:
        """(..., n) curvature and heading contributed by each curve at ``x``."""
        u = np.asarray(x, dtype=float)[..., None] - np.asarray(self.starts)
        t, n, k = (np.asarray(a) for a in (self.transitions, self.lengths, self.curvatures))
        ts = np.where(t > 0, t, 1.0)
        w = u - t - n
        kap = np.where(u < 0, 0.0, np.where(u < t, u / ts, np.where(w <= 0, 1.0, np.where(w < t, 1 - w / ts, 0.0))))
        th = np.where(u <= 0, 0.0, np.where(u <= t, u * u / (2 * ts), np.where(
            w <= 0, t / 2 + (u - t), np.where(w <= t, t / 2 + n + w - w * w / (2 * ts), t + n))))
        return kap * k, th * k

    def curvature(self, x) -> np.ndarray:
        """Signed curvature (1/m, + right) of the reference line at road ``x`` (m)."""
        return self._parts(x)[0].sum(-1)

    def theta(self, x) -> np.ndarray:
        """Heading (rad, + right) of the reference line at road ``x`` (m)."""
        return self._parts(x)[1].sum(-1)

    # -------------------------------------------------------------- centre line
    def centre(self, x) -> np.ndarray:
        """(..., 2) horizontal position (road frame: x, y right; m) of the reference line at road ``x``."""
        x = np.asarray(x, dtype=float)
        xs, cum = self._grid
        k = np.clip(np.searchsorted(xs, x, side="right") - 1, 0, len(xs) - 1)
        x0 = np.clip(x, xs[0], xs[-1])
        inside = cum[k] + _simpson(self, xs[k], x0)
        before = np.stack([x, np.zeros_like(x)], axis=-1)
        th_end = self.theta(xs[-1])
        after = cum[-1] + (x - xs[-1])[..., None] * np.stack([np.cos(th_end), np.sin(th_end)], -1)
        return np.where((x < xs[0])[..., None], before, np.where((x > xs[-1])[..., None], after, inside))

    def to_plane(self, x, y) -> np.ndarray:
        """(..., 2) horizontal position (road frame, m) of road point ``(x, y)``: ``C(x) + y n(x)``."""
        th = self.theta(x)
        return self.centre(x) + np.asarray(y, dtype=float)[..., None] * np.stack([-np.sin(th), np.cos(th)], -1)

    def from_plane(self, p: np.ndarray, iterations: int = 8) -> tuple[np.ndarray, np.ndarray]:
        """Road coordinates ``(x, y)`` (m) of horizontal positions ``p`` (..., 2): the foot of the
        perpendicular on the reference line (Newton from the nearest grid node)."""
        p = np.asarray(p, dtype=float)
        xs, cum = self._grid
        x = np.where(p[..., 0] < xs[0], p[..., 0], xs[np.argmin(np.linalg.norm(
            p[..., None, :] - cum, axis=-1), axis=-1)])
        for _ in range(iterations):
            th, d = self.theta(x), p - self.centre(x)
            along = d[..., 0] * np.cos(th) + d[..., 1] * np.sin(th)
            y = -d[..., 0] * np.sin(th) + d[..., 1] * np.cos(th)
            x = x + along / (1 - self.curvature(x) * y)
        th, d = self.theta(x), p - self.centre(x)
        return x, -d[..., 0] * np.sin(th) + d[..., 1] * np.cos(th)

    def breakpoints(self) -> np.ndarray:
        """Sorted ``x`` where the curvature stops being linear in ``x`` (each clothoid's and arc's ends)."""
        return self.curved_x(math.inf)

    def curved_x(self, step_m: float) -> np.ndarray:
        """``x`` samples at most ``step_m`` apart over every curve, with its ends: a chord between
        them departs from the arc by at most ``step^2 / (8 R')`` at the radius ``R'`` of the line."""
        xs = []
        for x0, t, n in zip(self.starts, self.transitions, self.lengths):
            for a, b in ((x0, x0 + t), (x0 + t, x0 + t + n), (x0 + t + n, x0 + 2 * t + n)):
                n = 1 if math.isinf(step_m) else max(1, int(math.ceil((b - a) / step_m)))
                xs.append(np.linspace(a, b, n + 1))
        return np.unique(np.concatenate(xs))

    def min_radius(self) -> float:
        """Smallest radius (m) on the plan."""
        return 1.0 / max(abs(k) for k in self.curvatures)


def path_length(plan: RoadPlan, profile, x0, x1, y) -> np.ndarray:
    """Signed length (m) along the road from road ``x0`` to ``x1`` on the line at lateral offset ``y``
    (m): ``int sqrt((1 - kappa y)^2 + slope^2) dx``; closed form ``x1 - x0 - y (theta(x1) - theta(x0))``
    without a vertical ``profile`` (:class:`~harness.world.road_profile.RoadProfile`), else 32-point
    Gauss-Legendre between consecutive breakpoints of the plan and the profile (the integrand is
    smooth inside each piece, and no node sits on a breakpoint)."""
    x0, x1, y = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (x0, x1, y)))
    if profile is None:
        return x1 - x0 - y * (plan.theta(x1) - plan.theta(x0))
    knots = np.union1d(plan.breakpoints(), profile.breakpoints())
    nodes, weights = np.polynomial.legendre.leggauss(32)
    out = np.empty(x0.shape)
    for i in np.ndindex(x0.shape):
        lo, hi = sorted((float(x0[i]), float(x1[i])))
        edges = np.r_[lo, knots[(knots > lo) & (knots < hi)], hi]
        xs = edges[:-1, None] + np.diff(edges)[:, None] * (nodes + 1) / 2
        f = np.hypot(1 - plan.curvature(xs) * y[i], profile.slope(xs))
        out[i] = np.sum(np.diff(edges) / 2 * (f @ weights)) * (1 if x1[i] >= x0[i] else -1)
    return out


def _simpson(plan: RoadPlan, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(..., 2) integral of (cos theta, sin theta) over [a, b] by Simpson's rule (one panel)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    th = plan.theta(np.stack([a, (a + b) / 2, b], axis=-1))
    f = np.stack([np.cos(th), np.sin(th)], axis=-1)              # (..., 3, 2)
    return (b - a)[..., None] / 6 * (f[..., 0, :] + 4 * f[..., 1, :] + f[..., 2, :])
