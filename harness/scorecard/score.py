"""Scorecard maths (no I/O): trials' ``warning.*`` metrics -> tests, false alarms, pooled risk.

* **Trial verdict.** A conflict trial (``rear_end``, ``cut_in``) passes when its first
  warning came at a true TTC of at least ``required_ttc_s`` (``warning.first_warning_ttc_s``;
  a warning that came before the collision course and stayed on into it is timed when the
  course began; one that ended before it has no true TTC and fails, as does no warning). A
  ``pass_by`` trial (a lane change that is no conflict) passes when no warning came.
* **Test verdict.** One entry per test and parameter combination (speed, gap,
  deceleration, offset): passed when at least ``min_trials_passed`` of its trials pass
  (NHTSA: 5 of 7).
* **False alarms** over the ``nominal`` runs: episodes whose span holds no truth
  conflict (:mod:`harness.scoring.warnings`), per hour and per km of simulated driving, each with its
  exact (Garwood) Poisson 95 % interval; against the target of at most ``FALSE_ALARM_TARGET_PER_H``
  per hour the verdict is PASS when the interval's upper end is at or below it, FAIL when it is
  above it, and "exposure too short" when even no false alarm would leave the upper end above it
  (under ``-ln(0.025) / target`` = 3.69 h for 1 per hour): :func:`rate_verdict`.
* **Risk** pooled over every run of the risk family: per frame, positive when a
  collision or a true TTC under 1 s (``risk_event``) occurs within the next ``h`` s,
  frames whose window runs past the run's end excluded unless already positive;
  AUROC (Mann-Whitney) and average precision (step-wise, as scikit-learn's
  ``average_precision_score``) of the 1/TTC risk, of the ``fcw`` warning stage's 1/TTC
  (``fcw_ttc``: its in-path test with its sigma margins and vetoes, within 10 s), of the
  adverse-manoeuvre 1/TTC (``manoeuvre_ttc``, :class:`monorarp.risk.estimators.ManoeuvreTTCRisk`) and, where the
  runs have it, the Monte Carlo probability, at each horizon. ``truth_reference`` scores the
  truth's own 1/TTC (no estimator): what a perfect state estimate would give a 1/TTC score.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from harness.scoring import algo

HORIZONS_S = (1.0, 2.0, 3.0)
FALSE_ALARM_TARGET_PER_H = 1.0     # false alarms per hour of nominal driving, at most
CONFIDENCE = 0.95


def poisson_interval(k: int, exposure: float, confidence: float = CONFIDENCE) -> tuple[float, float | None]:
    """Exact (Garwood) two-sided interval of a Poisson rate: ``k`` events in ``exposure`` (h, km, ...).

    Lower ``chi2(a/2; 2k) / 2T`` (0 for k = 0), upper ``chi2(1 - a/2; 2k + 2) / 2T``; for k = 0 the upper
    end is ``-ln(a/2) / T`` (3.689 / T at 95 %). Upper None when there is no exposure.
    """
    from scipy.stats import chi2

    if k < 0:
        raise ValueError(f"k must be >= 0, got {k}")
    if not exposure > 0:
        return 0.0, None
    a = 1.0 - confidence
    lo = float(chi2.ppf(a / 2, 2 * k)) / (2 * exposure) if k > 0 else 0.0
    return lo, float(chi2.ppf(1 - a / 2, 2 * k + 2)) / (2 * exposure)


def rate_verdict(k: int, hours: float, target: float = FALSE_ALARM_TARGET_PER_H,
                 confidence: float = CONFIDENCE) -> str:
    """``PASS``, ``FAIL`` or ``exposure too short to show ≤ 1 per hour`` for ``k`` events in ``hours``
    of driving against a rate of at most ``target`` per hour (module docstring)."""
    best = poisson_interval(0, hours, confidence)[1]
    if best is None or best > target:
        return f"exposure too short to show ≤ {target:g} per hour"
    return "PASS" if poisson_interval(k, hours, confidence)[1] <= target else "FAIL"


def exposure_needed(target: float, confidence: float = CONFIDENCE) -> float:
    """The exposure (h) at which no event at all shows a rate of at most ``target`` (per h)."""
    return poisson_interval(0, 1.0, confidence)[1] / target


def proportion_interval(k: int, n: int, confidence: float = CONFIDENCE) -> tuple[float, float] | None:
    """Exact (Clopper-Pearson) two-sided interval of a proportion ``k / n``; None when ``n`` is 0."""
    from scipy.stats import beta

    if n <= 0:
        return None
    a = 1.0 - confidence
    lo = float(beta.ppf(a / 2, k, n - k + 1)) if k > 0 else 0.0
    hi = float(beta.ppf(1 - a / 2, k + 1, n - k)) if k < n else 1.0
    return lo, hi


def trial_passed(kind: str, warning: Mapping, required_ttc_s: float | None) -> bool:
    """The verdict of one trial from its ``warning`` metrics (module docstring)."""
    if kind == "pass_by":
        return int(warning.get("episodes") or 0) == 0
    ttc = warning.get("first_warning_ttc_s")
    return ttc is not None and required_ttc_s is not None and ttc >= required_ttc_s - 1e-9


def average_precision(scores: Sequence[float] | np.ndarray, labels: Sequence[bool] | np.ndarray) -> float:
    """Average precision: sum over thresholds of (R_n - R_{n-1}) P_n (ties grouped); nan without positives."""
    s = np.asarray(scores, dtype=float)
    y = np.asarray(labels, dtype=bool)
    if s.shape != y.shape:
        raise ValueError("scores and labels must have the same length")
    n_pos = int(y.sum())
    if n_pos == 0:
        return float("nan")
    order = np.argsort(-s, kind="mergesort")
    s, y = s[order], y[order]
    last = np.r_[np.flatnonzero(np.diff(s)), s.size - 1]     # last index of each distinct score
    tp = np.cumsum(y)[last]
    fp = (last + 1) - tp
    precision = tp / (tp + fp)
    recall = tp / n_pos
    return float(np.sum(np.diff(np.r_[0.0, recall]) * precision))


def roc_curve(scores: np.ndarray, labels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(false positive rate, true positive rate) at every distinct threshold, from (0, 0) to (1, 1)."""
    s, y = np.asarray(scores, dtype=float), np.asarray(labels, dtype=bool)
    order = np.argsort(-s, kind="mergesort")
    s, y = s[order], y[order]
    last = np.r_[np.flatnonzero(np.diff(s)), s.size - 1] if s.size else np.array([], dtype=int)
    tp, fp = np.cumsum(y)[last], (last + 1) - np.cumsum(y)[last]
    n1, n0 = max(int(y.sum()), 1), max(int((~y).sum()), 1)
    return np.r_[0.0, fp / n0], np.r_[0.0, tp / n1]


def _pooled(runs: Sequence[Mapping[str, np.ndarray]], name: str, h: float) -> tuple[np.ndarray, np.ndarray, int]:
    """Scores and labels of estimator ``name`` at horizon ``h`` (s) pooled over the runs that have it."""
    scores, labels = [], []
    for r in runs:
        if name not in r or len(r["t"]) == 0:
            continue
        t = np.asarray(r["t"], dtype=float)
        dt = float(np.median(np.diff(t))) if t.size > 1 else 1.0
        lab = algo.horizon_labels(np.asarray(r["event"], dtype=bool), int(round(h / dt)))
        ok = np.isfinite(lab)
        scores.append(np.asarray(r[name], dtype=float)[ok])
        labels.append(lab[ok] == 1)
    s = np.concatenate(scores) if scores else np.array([])
    y = np.concatenate(labels) if labels else np.array([], dtype=bool)
    return s, y, len(scores)


def _names(runs: Sequence[Mapping[str, np.ndarray]]) -> list[str]:
    return sorted({k for r in runs for k in r if k not in ("t", "event")})


def roc_curves(runs: Sequence[Mapping[str, np.ndarray]], h: float) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """ROC curve of each estimator at horizon ``h`` (s), pooled."""
    out = {}
    for name in _names(runs):
        s, y, _ = _pooled(runs, name, h)
        if y.any() and (~y).any():
            out[name] = roc_curve(s, y)
    return out


def pooled_risk(runs: Sequence[Mapping[str, np.ndarray]], horizons_s: Sequence[float] = HORIZONS_S) -> dict:
    """AUROC and AP per horizon and estimator over runs' per-frame arrays.

    Each run: ``t`` (s), ``event`` (bool), and one score array per estimator name
    (``inverse_ttc``, ``monte_carlo``, ``fcw_ttc``, ``manoeuvre_ttc``; an estimator missing from some run is scored on
    the runs that have it).
    """
    out: dict = {}
    for h in horizons_s:
        per: dict = {}
        for name in _names(runs):
            s, y, n_runs = _pooled(runs, name, h)
            per[name] = {"auroc": algo.auroc(s, y), "ap": average_precision(s, y), "frames": int(y.size),
                         "positives": int(y.sum()), "runs": n_runs}
        out[f"{h:g}s"] = per
    return out
