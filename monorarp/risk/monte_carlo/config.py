"""The Monte Carlo risk estimator's settings: :class:`MonteCarloConfig` (units: m, m/s, m/s^2, s).

Every setting of :class:`monorarp.risk.monte_carlo.estimator.MonteCarloRisk` with its default, its
valid range (a field constraint) and a one-line description; what they do: docs/monte_carlo_risk.md.
:func:`monte_carlo_config` builds one from keyword overrides (the registry's ``kwargs``: a pipeline
config's ``risk.kwargs``, a sweep variant's ``risk_kwargs``, the CLI's ``--speed``) and refuses a bad
value with one line naming the field.
Frames: the ego frame of :mod:`monorarp.core.camera` (x right, y ahead).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, InstanceOf, field_validator

from monorarp.core.errors import UserError
from monorarp.core.settings import with_overrides
from monorarp.risk.monte_carlo.drivers import DriverDistribution
from monorarp.risk.monte_carlo.scene import Noise

BACKENDS = ("auto", "numba", "numpy")


class MonteCarloConfigError(UserError, ValueError):
    """A bad setting of :class:`~monorarp.risk.monte_carlo.estimator.MonteCarloRisk` (one line naming it)."""


class MonteCarloConfig(BaseModel):
    """Settings of the Monte Carlo risk estimator (module docstring)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    # Sampling and scoring
    n_rollouts: int = Field(500, ge=1, description="futures simulated per frame")
    horizon_s: float = Field(10.0, gt=0, description="how far ahead each future is simulated (s)")
    dt: float = Field(0.2, gt=0, description="rollout time step (s); why 0.2: MonteCarloRisk's docstring")
    seed: int = Field(0, description="seed of the sampled drivers and noise (drawn per (seed, track id))")
    score: Literal["probability", "inverse_ttc"] = Field("probability", description=(
        "risk reported: share of futures with a conflict (0..1), or the paper's mean 1/t_collision (1/s)"))
    near_miss_ttc_s: float = Field(1.0, description="a contact predicted within this (s) is a conflict")

    # Ego
    ego_speed_mps: float | None = Field(None, description=(
        "configured ego speed (m/s), used when assess and set_ego_speed give none; None: 25 m/s fallback"))
    ego_model: Literal["idm", "constant_speed"] = Field("idm", description=(
        "idm: the ego drives as the others do; constant_speed: it holds its speed and lane"))
    ego_lane_changes: bool = Field(True, description="may the ego change lane (ego_model idm only)")

    # Road and vehicles
    lane_width_m: float = Field(3.7, gt=0, description="lane width (m)")
    lanes_left: int | None = Field(None, description=(
        "lanes left of the ego's; None: those the vehicles span"))
    lanes_right: int | None = Field(None, description=(
        "lanes right of the ego's; None: those the vehicles span"))
    vehicle_length_m: float = Field(4.5, description="assumed length (m) of another vehicle")
    vehicle_width_m: float = Field(1.8, description="assumed width (m) of another vehicle")
    ego_length_m: float = Field(4.5, description="ego length (m)")
    ego_width_m: float = Field(1.8, description="ego width (m)")
    camera_forward_offset_m: float = Field(0.0, description=(
        "camera this far (m) ahead of the ego's centre; the run's camera, when given, sets it"))
    camera_lateral_offset_m: float = Field(0.0, description=(
        "camera this far (m) right of the ego's centre; the run's camera, when given, sets it"))

    # Driver model
    lateral_lookahead_s: float = Field(1.0, description=(
        "a vehicle's lane is the one its lateral velocity reaches in this time (s)"))
    mobil_interval_s: float = Field(1.0, description="period (s) of the MOBIL lane-change decisions")
    lane_change_duration_s: float = Field(3.0, description="time (s) a lane change takes")
    lane_change_cooldown_s: float = Field(4.0, description="at most one lane change per vehicle per this time (s)")
    decel_limit_mps2: float = Field(8.0, description="strongest braking (m/s^2, tyre-road friction)")
    noise: InstanceOf[Noise] = Field(default_factory=Noise, description=(
        "initial-state noise std devs (m, m/s; scene.Noise, or a mapping of its fields)"))
    drivers: InstanceOf[DriverDistribution] = Field(default_factory=DriverDistribution, description=(
        "distributions of the sampled IDM/MOBIL driver parameters (drivers.DriverDistribution)"))

    # Implementation
    dtype: str = Field("float32", description="state dtype of the numpy backend (numba computes in float64)")
    backend: Literal["auto", "numba", "numpy"] = Field("auto", description=(
        "rollout implementation; auto: numba when importable, else numpy"))
    warm_up: bool = Field(True, description="compile the numba kernel in the constructor, not on the first frame")

    @field_validator("noise", mode="before")
    @classmethod
    def _noise_from_mapping(cls, v: Any) -> Any:
        """A mapping of :class:`Noise`'s fields becomes one; None the default."""
        if v is None:
            return Noise()
        if isinstance(v, Mapping):
            unknown = sorted(set(v) - set(Noise.__dataclass_fields__))
            if unknown:
                raise ValueError(f"unknown noise field(s) {', '.join(unknown)}; fields: "
                                 f"{', '.join(Noise.__dataclass_fields__)}")
            return Noise(**v)
        return v

    @field_validator("drivers", mode="before")
    @classmethod
    def _default_drivers(cls, v: Any) -> Any:
        """None: the default distributions."""
        return DriverDistribution() if v is None else v


def monte_carlo_config(base: MonteCarloConfig | None = None,
                       overrides: Mapping[str, Any] | None = None) -> MonteCarloConfig:
    """``base`` (default: the defaults) with ``overrides`` validated in; :class:`MonteCarloConfigError` if bad."""
    return with_overrides(MonteCarloConfig, base, overrides, "monte_carlo risk", MonteCarloConfigError)
