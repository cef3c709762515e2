"""How far a pooled tracking score could move with another draw of sequences: a sequence bootstrap.

A score pooled over sequences (motmetrics' "OVERALL": sums of counts, then the ratio) is a
ratio estimate over a sample of sequences; its uncertainty is dominated by how different the
sequences are (a hard clip against an easy one), not by the frames inside one. The bootstrap here
resamples whole sequences with replacement (``n_resamples`` draws of ``n`` sequences, seeded),
recomputes the pooled ratio from the drawn sequences' summed counts, and reports the percentile
interval. Trackers run on the same sequences are resampled with the *same* draws (paired), so the
interval of a difference between two trackers reflects only how their gaps vary from sequence
to sequence. Checked against ``scipy.stats.bootstrap`` (``paired=True``, percentile method) in
tests/test_bootstrap.py.

Per sequence, with the counts of ``metrics.json``'s ``tracking`` section:

* MOTA = 1 - sum(misses + false positives + id switches) / sum(objects);
* IDF1 = 2 sum(IDTP) / sum(objects + predictions), IDTP = IDR x objects,
  predictions = objects - misses + false positives.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

LEVEL = 0.95
RESAMPLES = 2000
SEED = 0


@dataclass(frozen=True)
class SequenceCounts:
    """One tracker's counts per sequence, arrays of shape (n,)."""

    objects: np.ndarray
    errors: np.ndarray      # misses + false positives + id switches
    idtp: np.ndarray
    predictions: np.ndarray

    @classmethod
    def from_tracking(cls, tracking: Sequence[Mapping]) -> "SequenceCounts":
        """From the ``tracking`` sections of the sequences' ``metrics.json`` (in sequence order)."""
        obj = np.array([int(t["objects"]) for t in tracking], dtype=float)
        miss = np.array([int(t["misses"]) for t in tracking], dtype=float)
        fp = np.array([int(t["false_positives"]) for t in tracking], dtype=float)
        sw = np.array([int(t["id_switches"]) for t in tracking], dtype=float)
        idr = np.array([float(t["idr"]) if int(t["objects"]) > 0 else 0.0 for t in tracking], dtype=float)
        return cls(objects=obj, errors=miss + fp + sw, idtp=idr * obj, predictions=obj - miss + fp)

    def mota(self, weights: np.ndarray) -> np.ndarray:
        """Pooled MOTA for each row of ``weights`` ((B, n) times each sequence is drawn); NaN: no objects."""
        obj = weights @ self.objects
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(obj > 0, 1.0 - (weights @ self.errors) / obj, np.nan)

    def idf1(self, weights: np.ndarray) -> np.ndarray:
        """Pooled IDF1 for each row of ``weights``; NaN: no objects and no predictions."""
        den = weights @ (self.objects + self.predictions)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(den > 0, 2.0 * (weights @ self.idtp) / den, np.nan)


def resample_weights(n: int, n_resamples: int = RESAMPLES, seed: int = SEED) -> np.ndarray:
    """(n_resamples, n): how many times each of ``n`` sequences is drawn in each resample (rows sum to n)."""
    if n < 1:
        raise ValueError(f"need at least one sequence, got {n}")
    rng = np.random.default_rng(seed)
    return rng.multinomial(n, np.full(n, 1.0 / n), size=n_resamples).astype(float)


def percentile_interval(values: np.ndarray, level: float = LEVEL) -> list[float] | None:
    """The central ``level`` percentile interval of the finite ``values``; None when there are none."""
    v = values[np.isfinite(values)]
    if not v.size:
        return None
    lo, hi = np.quantile(v, [(1 - level) / 2, (1 + level) / 2])
    return [float(lo), float(hi)]


def tracker_intervals(counts: Mapping[str, SequenceCounts], reference: str, level: float = LEVEL,
                      n_resamples: int = RESAMPLES, seed: int = SEED) -> dict:
    """Percentile intervals of each tracker's pooled MOTA and IDF1 and of its difference from ``reference``
    (tracker minus reference; not for the reference itself), all from the same sequence draws.

    ``counts``: tracker -> its :class:`SequenceCounts`, all over the same sequences in the same order.
    """
    if reference not in counts:
        raise ValueError(f"reference tracker {reference!r} is not among {sorted(counts)}")
    n = len(counts[reference].objects)
    if any(len(c.objects) != n for c in counts.values()):
        raise ValueError("every tracker needs counts for the same sequences")
    w = resample_weights(n, n_resamples, seed)
    ref = {"mota": counts[reference].mota(w), "idf1": counts[reference].idf1(w)}
    out = {}
    for name, c in counts.items():
        draws = {"mota": c.mota(w), "idf1": c.idf1(w)}
        entry = {k: percentile_interval(v, level) for k, v in draws.items()}
        if name != reference:
            entry |= {f"{k}_minus_reference": percentile_interval(v - ref[k], level) for k, v in draws.items()}
        out[name] = entry
    return {"level": level, "resamples": n_resamples, "seed": seed, "sequences": n, "reference": reference,
            "trackers": out}
