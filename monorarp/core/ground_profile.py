"""A measured road profile, as the horizon stage hands it to the state stage (data only).

:class:`GroundProfile`: the road's ego distance per image row, measured from the lane lines' spacing
(how: :mod:`monorarp.horizon.ground_profile`); :class:`GroundReading`: a
:class:`~monorarp.core.types.HorizonReading` that carries one. How the state estimator uses it:
:mod:`monorarp.state.ground_contact`. The method and its measured figures: docs/road_profile.md.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from monorarp.core.types import HorizonReading


@dataclass(frozen=True)
class GroundProfile:
    """The road's ego distance per image row, measured from the lane lines' spacing.

    ``rows`` (px, increasing), ``dist`` (m, ego ``y`` of the road seen at each row) and ``dist_std``
    (m, one-sigma) of the rows the lines were followed on; ``fallback_grade_std`` (rise/run): the grade
    uncertainty a row outside the profile is stated with (the flat-ground estimate there);
    ``open_end``: the lines were lost above ``rows[0]`` while still apart (a crest hides the road
    beyond, or traffic covers it), so a box whose bottom lies within ``end_margin_px`` of that row may
    stand anywhere beyond it.
    """

    rows: np.ndarray
    dist: np.ndarray
    dist_std: np.ndarray
    fallback_grade_std: float = 0.02
    open_end: bool = False
    end_margin_px: float = 3.0

    def at(self, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(distance m, one-sigma m, ``|d distance / d row|`` m/px) at rows ``v``; NaN outside the profile."""
        v = np.asarray(v, dtype=float)
        nan = np.full_like(v, np.nan)
        if self.rows.size < 2:
            return nan, nan, nan
        inside = (v >= self.rows[0]) & (v <= self.rows[-1])
        d = np.interp(v, self.rows, self.dist)
        s = np.interp(v, self.rows, self.dist_std)
        i = np.clip(np.searchsorted(self.rows, v) - 1, 0, self.rows.size - 2)
        gain = np.abs(self.dist[i + 1] - self.dist[i]) / (self.rows[i + 1] - self.rows[i])
        return np.where(inside, d, nan), np.where(inside, s, nan), np.where(inside, gain, nan)


@dataclass(frozen=True)
class GroundReading(HorizonReading):
    """A horizon reading that also carries the frame's measured :class:`GroundProfile` (None: none)."""

    profile: GroundProfile | None = None
