"""Sampled driver parameters (IDM + MOBIL) and initial-state noise, truncated to physical ranges.

Every parameter is a normal distribution truncated to ``[lo, hi]`` (SI units), drawn per driver
(one ``(K, S)`` block per tracked vehicle, keyed on its track id: common random numbers).
The default ranges and their sources: docs/monte_carlo_risk.md.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.special import ndtr, ndtri


@dataclass(frozen=True)
class Truncated:
    """Normal(mean, std) truncated to [lo, hi]."""

    mean: float
    std: float
    lo: float
    hi: float

    def __post_init__(self) -> None:
        if not (self.std > 0 and self.lo <= self.mean <= self.hi and self.lo < self.hi):
            raise ValueError(f"bad truncated normal {self}")

    def from_uniform(self, u: np.ndarray) -> np.ndarray:
        """Map uniforms in [0, 1) to draws of this distribution (inverse CDF)."""
        return self.mean + self.std * std_truncated_from_uniform(
            u, (self.lo - self.mean) / self.std, (self.hi - self.mean) / self.std)


def std_truncated_from_uniform(u: np.ndarray, z_lo: float, z_hi: float) -> np.ndarray:
    """Standard normal truncated to [z_lo, z_hi] from uniforms (inverse CDF), clipped for round-off."""
    p_lo, p_hi = ndtr(z_lo), ndtr(z_hi)
    return np.clip(ndtri(p_lo + u * (p_hi - p_lo)), z_lo, z_hi)


# Rows of a driver block.
PARAM_NAMES = ("T", "s0", "a", "b", "politeness", "threshold", "b_safe")
ROW_Z_V0, ROW_NX, ROW_NY, ROW_NV = 7, 8, 9, 10
N_ROWS = 11


@dataclass(frozen=True)
class DriverDistribution:
    """Distributions of the sampled driver parameters (see the module table)."""

    T: Truncated = Truncated(1.5, 0.4, 0.8, 2.5)
    s0: Truncated = Truncated(2.0, 0.7, 1.0, 4.0)
    a: Truncated = Truncated(1.5, 0.5, 0.5, 3.0)
    b: Truncated = Truncated(2.0, 0.6, 1.0, 4.0)
    politeness: Truncated = Truncated(0.3, 0.2, 0.0, 1.0)
    threshold: Truncated = Truncated(0.2, 0.1, 0.05, 0.6)
    b_safe: Truncated = Truncated(3.0, 1.0, 1.5, 5.0)
    v0_rel_std: float = 0.10      # desired-speed spread, fraction of the current speed
    v0_min_std_mps: float = 1.0
    v0_z_max: float = 2.0
    v0_floor_mps: float = 0.5
    noise_z_max: float = 3.0

    def draw_block(self, rng: np.random.Generator, n_samples: int) -> np.ndarray:
        """One driver's ``(N_ROWS, S)`` block: 7 parameters, desired-speed z and 3 noise deviates."""
        u = rng.random((N_ROWS, n_samples))
        out = np.empty_like(u)
        for row, name in enumerate(PARAM_NAMES):
            out[row] = getattr(self, name).from_uniform(u[row])
        out[ROW_Z_V0] = std_truncated_from_uniform(u[ROW_Z_V0], -self.v0_z_max, self.v0_z_max)
        out[ROW_NX:] = std_truncated_from_uniform(u[ROW_NX:], -self.noise_z_max, self.noise_z_max)
        return out

    def desired_speed(self, v: np.ndarray, z: np.ndarray) -> np.ndarray:
        """IDM desired speed (m/s) around the current absolute speed ``v``."""
        sigma = np.maximum(self.v0_min_std_mps, self.v0_rel_std * np.abs(v))
        return np.maximum(v + sigma * z, self.v0_floor_mps)


@dataclass
class DriverParams:
    """Per-rollout, per-vehicle driver parameters, arrays of shape (S, N)."""

    v0: np.ndarray
    T: np.ndarray
    s0: np.ndarray
    a: np.ndarray
    b: np.ndarray
    politeness: np.ndarray
    threshold: np.ndarray
    b_safe: np.ndarray
    extra: dict = field(default_factory=dict)

    @classmethod
    def uniform(cls, shape: tuple[int, int], v0, T=1.5, s0=2.0, a=1.5, b=2.0,
                politeness=0.0, threshold=0.2, b_safe=2.0) -> "DriverParams":
        """Every driver alike (broadcast scalars or arrays to ``shape``); for tests and parity checks."""
        f = lambda x: np.broadcast_to(np.asarray(x, dtype=float), shape).copy()  # noqa: E731
        return cls(f(v0), f(T), f(s0), f(a), f(b), f(politeness), f(threshold), f(b_safe))

    @classmethod
    def from_blocks(cls, blocks: np.ndarray, v: np.ndarray, dist: DriverDistribution) -> "DriverParams":
        """``blocks`` (N_ROWS, S, N) of :meth:`DriverDistribution.draw_block` rows; ``v`` (S, N) speeds."""
        return cls(dist.desired_speed(v, blocks[ROW_Z_V0]), *(blocks[i] for i in range(len(PARAM_NAMES))))
