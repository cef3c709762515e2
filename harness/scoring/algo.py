"""Pure scoring maths (no I/O): error statistics, range bins, warnings, precision/recall.

Every statistic over an empty set is ``nan``; :mod:`harness.scoring.evaluate`
turns ``nan`` into JSON ``null`` ("nothing to score").
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from monorarp.warning.thresholds import TTC_CUE_THRESHOLD_S

#: Longitudinal range bins of the ground-truth distance ``d_long`` (m), [lo, hi).
RANGE_BINS: dict[str, tuple[float, float]] = {
    "0-10": (0.0, 10.0),
    "10-20": (10.0, 20.0),
    "20-40": (20.0, 40.0),
    "40-80": (40.0, 80.0),
}
#: Wider spans the issue's accuracy targets are stated over (m), [lo, hi).
TARGET_SPANS: dict[str, tuple[float, float]] = {"5-40": (5.0, 40.0), "40-80": (40.0, 80.0)}

#: Two-sided 90 % normal quantile: the stated distance interval is est +- Z90 * std.
Z90 = 1.6448536269514722


def _nan_stat(fn, x: np.ndarray) -> float:
    return float(fn(x)) if x.size else float("nan")


def summary(values: Sequence[float] | np.ndarray, prefix: str = "", unit: str = "") -> dict[str, float]:
    """Median, mean and 90th percentile of ``values`` (NaNs dropped), keyed ``{prefix}median{unit}``..."""
    x = np.asarray(values, dtype=float)
    x = x[np.isfinite(x)]
    return {
        f"{prefix}median{unit}": _nan_stat(np.median, x),
        f"{prefix}mean{unit}": _nan_stat(np.mean, x),
        f"{prefix}p90{unit}": _nan_stat(lambda v: np.percentile(v, 90), x),
    }


def error_stats(est: Sequence[float] | np.ndarray, gt: Sequence[float] | np.ndarray,
                relative: bool = True, unit: str = "_m") -> dict[str, float | int]:
    """Errors of ``est`` against ``gt`` over the pairs where both are finite.

    Absolute error |est - gt| (median/mean/p90, key suffix ``unit``), the signed
    bias mean(est - gt), and with ``relative`` the relative error
    |est - gt| / |gt| (pairs with gt == 0 excluded from it). ``count`` = pairs scored.
    """
    est = np.asarray(est, dtype=float)
    gt = np.asarray(gt, dtype=float)
    ok = np.isfinite(est) & np.isfinite(gt)
    err = est[ok] - gt[ok]
    out: dict[str, float | int] = {"count": int(ok.sum())}
    out.update(summary(np.abs(err), "abs_err_", unit))
    out[f"bias{unit}"] = _nan_stat(np.mean, err)
    if relative:
        g = gt[ok]
        nz = g != 0
        out.update(summary(np.abs(err[nz]) / np.abs(g[nz]), "rel_err_"))
    return out


def interval_stats(est, std, gt, z: float = Z90) -> dict[str, float | int]:
    """Coverage and width of the intervals ``est +- z std`` against ``gt`` (pairs where all three are finite).

    ``interval_coverage``: share of pairs with ``|est - gt| <= z std``; ``interval_width_median_m`` /
    ``_mean_m``: the full width ``2 z std`` (m); ``interval_count``: pairs scored.
    """
    est, std, gt = (np.asarray(a, dtype=float) for a in (est, std, gt))
    ok = np.isfinite(est) & np.isfinite(std) & np.isfinite(gt)
    inside = np.abs(est[ok] - gt[ok]) <= z * std[ok]
    width = 2 * z * std[ok]
    return {"interval_count": int(ok.sum()), "interval_coverage": _nan_stat(np.mean, inside.astype(float)),
            "interval_width_median_m": _nan_stat(np.median, width), "interval_width_mean_m": _nan_stat(np.mean, width)}


def bin_labels(d_long: Sequence[float] | np.ndarray, bins: dict[str, tuple[float, float]] = RANGE_BINS) -> np.ndarray:
    """The bin label of each distance (object array; None outside every bin)."""
    d = np.asarray(d_long, dtype=float)
    labels = np.full(d.shape, None, dtype=object)
    for name, (lo, hi) in bins.items():
        labels[(d >= lo) & (d < hi)] = name
    return labels


def binned_error_stats(est, gt, d_long, bins: dict[str, tuple[float, float]] = RANGE_BINS,
                       relative: bool = True, unit: str = "_m") -> dict[str, dict[str, float | int]]:
    """:func:`error_stats` within each range bin of the ground-truth ``d_long`` (m)."""
    est, gt, d = (np.asarray(a, dtype=float) for a in (est, gt, d_long))
    return {name: error_stats(est[(d >= lo) & (d < hi)], gt[(d >= lo) & (d < hi)], relative, unit)
            for name, (lo, hi) in bins.items()}


def ratio(num: int, den: int) -> float:
    """num / den, nan when den == 0."""
    return num / den if den else float("nan")


def precision_recall(tp: int, n_pred: int, n_true: int) -> dict[str, float | int]:
    """Precision tp/n_pred and recall tp/n_true (nan when the denominator is 0), plus the counts."""
    if not 0 <= tp <= min(n_pred, n_true):
        raise ValueError(f"inconsistent counts tp={tp}, predicted={n_pred}, true={n_true}")
    p, r = ratio(tp, n_pred), ratio(tp, n_true)
    f1 = 2 * p * r / (p + r) if (np.isfinite(p) and np.isfinite(r) and p + r > 0) else float("nan")
    return {"precision": p, "recall": r, "f1": f1, "tp": tp, "fp": n_pred - tp, "fn": n_true - tp}


def warnings_from_ttc(ttc: Sequence[float | None] | np.ndarray, threshold_s: float = TTC_CUE_THRESHOLD_S) -> np.ndarray:
    """Warning flags: TTC known (not None/NaN) and strictly below ``threshold_s``."""
    t = np.array([np.nan if v is None else v for v in ttc], dtype=float)
    with np.errstate(invalid="ignore"):
        return np.isfinite(t) & (t < threshold_s)


def warning_classification(ttc_est, ttc_gt, threshold_s: float = TTC_CUE_THRESHOLD_S) -> dict[str, float | int]:
    """Precision/recall of estimated TTC warnings against ground-truth ones, pair by pair.

    ``ttc_est``/``ttc_gt``: the TTC (s, None/NaN = no collision within the horizon)
    of the same object-frames. Precision is nan when nothing was warned, recall
    nan when nothing should have been.
    """
    w_est = warnings_from_ttc(ttc_est, threshold_s)
    w_gt = warnings_from_ttc(ttc_gt, threshold_s)
    if w_est.shape != w_gt.shape:
        raise ValueError("ttc_est and ttc_gt must have the same length")
    out = precision_recall(int((w_est & w_gt).sum()), int(w_est.sum()), int(w_gt.sum()))
    out["threshold_s"] = float(threshold_s)
    return out


# ----------------------------------------------------------------------------- risk scoring
def average_ranks(x: Sequence[float] | np.ndarray) -> np.ndarray:
    """1-based ranks of ``x`` with ties given the mean of the ranks they span."""
    x = np.asarray(x, dtype=float)
    _, inverse, counts = np.unique(x, return_inverse=True, return_counts=True)
    upper = np.cumsum(counts)                  # last rank of each distinct value
    return (upper - (counts - 1) / 2.0)[inverse]


def auroc(scores: Sequence[float] | np.ndarray, labels: Sequence[bool] | np.ndarray) -> float:
    """Area under the ROC curve of ``scores`` for binary ``labels`` (Mann-Whitney U / (n1 n0)).

    Ties count one half (average ranks). ``nan`` when either class is empty.
    """
    s = np.asarray(scores, dtype=float)
    y = np.asarray(labels, dtype=bool)
    if s.shape != y.shape:
        raise ValueError("scores and labels must have the same length")
    n1, n0 = int(y.sum()), int((~y).sum())
    if n1 == 0 or n0 == 0:
        return float("nan")
    u = average_ranks(s)[y].sum() - n1 * (n1 + 1) / 2.0
    return float(u / (n1 * n0))


def brier(prob: Sequence[float] | np.ndarray, labels: Sequence[bool] | np.ndarray) -> float:
    """Mean squared difference between probabilities in [0, 1] and 0/1 outcomes (nan when empty)."""
    p = np.asarray(prob, dtype=float)
    y = np.asarray(labels, dtype=float)
    if p.shape != y.shape:
        raise ValueError("prob and labels must have the same length")
    if p.size and not ((p >= 0) & (p <= 1)).all():
        raise ValueError("probabilities must lie in [0, 1]")
    return _nan_stat(np.mean, (p - y) ** 2)


def inverse_ttc_probability(risk: Sequence[float] | np.ndarray, scale_s: float = 1.0) -> np.ndarray:
    """Map the paper's risk 1/TTC (1/s) to a probability: ``min(1, risk * scale_s)``.

    With ``scale_s`` = the near-miss threshold (1 s): a TTC at or under it gives 1, a TTC
    of 2 s gives 0.5, no collision course (risk 0) gives 0.
    """
    return np.clip(np.asarray(risk, dtype=float) * scale_s, 0.0, 1.0)


def horizon_labels(event: Sequence[bool] | np.ndarray, horizon_frames: int) -> np.ndarray:
    """Label of frame k: does ``event`` occur in frames k .. k + horizon_frames? (float; nan = excluded).

    A frame whose window runs past the last frame is labelled only when the event is
    already seen within the frames that exist (1); otherwise it is excluded (nan),
    since the run does not say what happened next.
    """
    e = np.asarray(event, dtype=bool)
    n = e.size
    if horizon_frames < 0:
        raise ValueError("horizon_frames must be >= 0")
    # next_event[k] = index of the first event at or after k (n when none).
    idx = np.where(e, np.arange(n), n)
    next_event = np.minimum.accumulate(idx[::-1])[::-1] if n else idx
    k = np.arange(n)
    positive = (next_event < n) & (next_event <= k + horizon_frames)
    complete = k + horizon_frames <= n - 1
    return np.where(positive, 1.0, np.where(complete, 0.0, np.nan))
