"""KITTI's difficulty levels (object benchmark): which labels each of easy, moderate and hard asks for.

A label passes a level when its box height ``y2 - y1`` (px) exceeds the level's minimum, its
occlusion level is at most the level's and its truncation (0..1) at most the level's (devkit rules).
"""

from __future__ import annotations

import numpy as np

#: KITTI object benchmark: (min box height px, max occlusion level, max truncation).
DIFFICULTIES: dict[str, tuple[float, int, float]] = {"easy": (40.0, 0, 0.15), "moderate": (25.0, 1, 0.30),
                                                     "hard": (25.0, 2, 0.50)}


def passes(box: np.ndarray, occluded: np.ndarray, truncated: np.ndarray, difficulty: str) -> np.ndarray:
    """(N,) does each object pass KITTI's ``difficulty`` filter? (devkit: height ``y2 - y1`` > min height,
    occlusion <= max, truncation <= max)."""
    min_h, max_occ, max_trunc = DIFFICULTIES[difficulty]
    b = np.asarray(box, dtype=float).reshape(-1, 4)
    return (b[:, 3] - b[:, 1] > min_h) & (np.asarray(occluded) <= max_occ) & (np.asarray(truncated) <= max_trunc)


def difficulty_names(box, occluded, truncated) -> list[str]:
    """The easiest KITTI difficulty each object passes ("" when none)."""
    ok = {d: passes(box, occluded, truncated, d) for d in DIFFICULTIES}
    n = len(np.asarray(box).reshape(-1, 4))
    return [next((d for d in DIFFICULTIES if ok[d][k]), "") for k in range(n)]
