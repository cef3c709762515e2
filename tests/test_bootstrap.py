"""The sequence bootstrap of pooled tracking scores, against scipy.stats.bootstrap."""

import numpy as np
import pytest
from scipy import stats

from harness.scoring.bootstrap import SequenceCounts, resample_weights, tracker_intervals

N_REF = 20000          # resamples on both sides: Monte Carlo error of a 2.5 % quantile ~0.1 of the CI width


def _tracking(objects, misses, fps, switches, idr):
    return [{"objects": o, "misses": m, "false_positives": f, "id_switches": s, "idr": r}
            for o, m, f, s, r in zip(objects, misses, fps, switches, idr)]


def _sequences(seed: int, n: int = 12):
    rng = np.random.default_rng(seed)
    obj = rng.integers(800, 2500, n)
    miss = (obj * rng.uniform(0.005, 0.09, n)).astype(int)
    fp = rng.integers(0, 60, n)
    sw = rng.integers(0, 8, n)
    idr = rng.uniform(0.85, 0.99, n)
    return obj, miss, fp, sw, idr


def _scipy_interval(data, statistic):
    res = stats.bootstrap(data, statistic, paired=True, vectorized=True, method="percentile",
                          n_resamples=N_REF, confidence_level=0.95, random_state=np.random.default_rng(7))
    return np.array([res.confidence_interval.low, res.confidence_interval.high])


def test_intervals_match_scipy_bootstrap():
    obj, miss, fp, sw, idr = _sequences(1)
    # a second tracker on the same sequences, better on some and worse on others, so that its gap to the
    # first varies by sequence and pairing matters (an unpaired interval of the gap is ~2.4x wider)
    gain = np.random.default_rng(2).uniform(0.3, 1.3, len(obj))
    miss_b, fp_b, sw_b, idr_b = (miss * gain).astype(int), fp + 5, sw, np.minimum(idr + 0.02, 1.0)
    a = _tracking(obj, miss, fp, sw, idr)
    b = _tracking(obj, miss_b, fp_b, sw_b, idr_b)
    out = tracker_intervals({"a": SequenceCounts.from_tracking(a), "b": SequenceCounts.from_tracking(b)},
                            reference="a", n_resamples=N_REF)

    def mota(o, e, axis=-1):
        return 1 - e.sum(axis) / o.sum(axis)

    def idf1(o, tp, p, axis=-1):
        return 2 * tp.sum(axis) / (o.sum(axis) + p.sum(axis))

    def mota_diff(o, ea, eb, axis=-1):
        return mota(o, eb, axis) - mota(o, ea, axis)

    err_a, err_b = miss + fp + sw, miss_b + fp_b + sw_b
    want_mota = _scipy_interval((obj, err_a), mota)
    want_idf1 = _scipy_interval((obj, idr * obj, obj - miss + fp), idf1)
    want_diff = _scipy_interval((obj, err_a, err_b), mota_diff)
    for got, want in ((out["trackers"]["a"]["mota"], want_mota), (out["trackers"]["a"]["idf1"], want_idf1),
                      (out["trackers"]["b"]["mota_minus_reference"], want_diff)):
        width = want[1] - want[0]
        assert width > 0.002                                  # a real spread, not a degenerate case
        np.testing.assert_allclose(got, want, atol=0.1 * width)
    # the point estimate (pooled over all sequences) lies inside its interval
    pooled = 1 - err_a.sum() / obj.sum()
    assert out["trackers"]["a"]["mota"][0] < pooled < out["trackers"]["a"]["mota"][1]
    assert "mota_minus_reference" not in out["trackers"]["a"]


def test_identical_sequences_give_a_point_interval():
    seqs = _tracking([1000] * 6, [50] * 6, [10] * 6, [2] * 6, [0.9] * 6)
    out = tracker_intervals({"p": SequenceCounts.from_tracking(seqs)}, reference="p")
    assert out["trackers"]["p"]["mota"] == pytest.approx([0.938, 0.938])
    assert out["trackers"]["p"]["idf1"] == pytest.approx([2 * 900 / (1000 + 960)] * 2)


def test_same_draws_every_call_and_rows_sum_to_n():
    w = resample_weights(5, 100, seed=3)
    assert w.shape == (100, 5) and (w.sum(axis=1) == 5).all()
    np.testing.assert_array_equal(w, resample_weights(5, 100, seed=3))


def test_mismatched_sequences_refused():
    one = SequenceCounts.from_tracking(_tracking([10], [1], [0], [0], [0.9]))
    two = SequenceCounts.from_tracking(_tracking([10, 12], [1, 2], [0, 0], [0, 0], [0.9, 0.8]))
    with pytest.raises(ValueError, match="same sequences"):
        tracker_intervals({"a": one, "b": two}, reference="a")
