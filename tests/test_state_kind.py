"""The per-track vehicle kind of the size prior (monorarp/state/kind.py and StateEstimator): a label flipping
from frame to frame changes neither the kind nor the range filter, a persistent change switches the kind after
the closed-form hysteresis window without a restart, the velocity survives it, a real jump still restarts, and
single images (KITTI) read as before."""

from __future__ import annotations

import math

import numpy as np
import pytest

from monorarp.core.camera import CameraModel
from monorarp.core.types import Track
from monorarp.state.config import StateConfigError
from monorarp.state.estimator import StateEstimator
from monorarp.state.kind import TrackKinds

CAM = CameraModel(width=1242, height=375, fx=721.5, fy=721.5, cx=609.6, cy=172.9, height_m=1.65)
DT = 0.04                                            # 25 frames/s
CAR, TRUCK = (1.5, 1.75), (3.2, 2.45)                # height, width (m): the size prior's means


def _box(d: float, size: tuple[float, float]) -> tuple[float, float, float, float]:
    """The rear face (height, width ``size``, m) of a vehicle ``d`` m ahead on the centre line, flat ground,
    pinhole: (x1, y1, x2, y2) px."""
    h, w = size
    bottom = CAM.cy + CAM.fy * CAM.height_m / d
    return (CAM.cx - CAM.fx * w / 2 / d, bottom - CAM.fy * h / d, CAM.cx + CAM.fx * w / 2 / d, bottom)


def _run(labels: list[str], size: tuple[float, float], **kw):
    """A vehicle closing from 45 m at 5 m/s, one track, ``labels`` per frame: per frame (t, true d, state, kind)."""
    est = StateEstimator(CAM, size_prior=True, contact_offset_m=0.0, **{"kind_memory_s": 1.0, **kw})
    out = []
    for k, lab in enumerate(labels):
        t = k * DT
        d = 45.0 - 5.0 * t
        out.append((t, d, est.update([Track(id=0, box=_box(d, size), label=lab, score=0.9)], t)[0],
                    est.track_kind(0)))
    return out


def test_an_alternating_label_keeps_the_first_kind_and_never_restarts() -> None:
    rows = _run(["car", "truck"] * 40, CAR)
    assert all(kind == "car" for *_, kind in rows)
    for t, d, st, _ in rows:
        assert st.age_s == pytest.approx(t)           # born at frame 0, never restarted
    t, d, st, _ = rows[-1]
    assert st.d_y == pytest.approx(d, rel=0.01)       # the car prior on a car's box: the truth
    assert st.v_y == pytest.approx(-5.0, abs=0.3) and st.v_y_std < 1.0
    # each box's own label (the old behaviour): the truck frames read far, the filter restarts at each flip
    plain = _run(["car", "truck"] * 40, CAR, kind_memory_s=None)
    assert sum(st.age_s == 0.0 for _, _, st, _ in plain) > 30


def _switch_frames(n_before: int, share: float, memory_s: float) -> int:
    """Closed form: after ``n_before`` votes for the old label (one per frame, equal scores), the number ``n`` of
    votes for the new one at which its share of the decayed votes reaches ``share``:
    ``(1 - l^n) >= share ((1 - l^n) + l^n (1 - l^n_before))`` with ``l = exp(-DT / memory_s)``."""
    lam = math.exp(-DT / memory_s)
    return math.ceil(math.log(1.0 + share / (1.0 - share) * (1.0 - lam ** n_before)) / -math.log(lam) - 1e-9)


def test_a_persistent_change_switches_after_the_window_without_a_restart() -> None:
    n = _switch_frames(50, 0.75, 1.0)
    assert n == 32                                    # 1.28 s after the change
    rows = _run(["car"] * 50 + ["truck"] * 60, TRUCK)
    kinds = [kind for *_, kind in rows]
    assert kinds[:50 + n - 1] == ["car"] * (50 + n - 1) and kinds[50 + n - 1:] == ["truck"] * (60 - n + 1)
    for t, d, st, _ in rows:
        assert st.age_s == pytest.approx(t)           # no restart at the switch
    # the truck's box read as a car's is far too near; as a truck's, the truth from the switch on
    assert rows[48][2].d_y < 0.6 * rows[48][1]
    for t, d, st, _ in rows[50 + n - 1:]:
        assert st.d_y == pytest.approx(d, rel=0.01)
    # with each box's own label the filter restarts at the change
    plain = _run(["car"] * 50 + ["truck"] * 60, TRUCK, kind_memory_s=None)
    assert plain[50][2].age_s == 0.0


def test_the_velocity_survives_a_kind_switch() -> None:
    n = _switch_frames(50, 0.75, 1.0)
    rows = _run(["car"] * 50 + ["truck"] * 60, TRUCK)
    before, at = rows[50 + n - 2][2], rows[50 + n - 1][2]
    # read under the car's prior the range is scaled down, and so is its rate: the time to contact is right
    assert before.d_y / -before.v_y == pytest.approx(rows[50 + n - 2][1] / 5.0, rel=0.05)
    # re-expressed under the truck's, the velocity is the true closing speed at once, not the prior's 0 +- 10
    assert at.v_y == pytest.approx(-5.0, abs=0.3)
    assert at.v_y_std < 1.0
    plain = _run(["car"] * 50 + ["truck"] * 60, TRUCK, kind_memory_s=None)
    assert plain[50][2].v_y == 0.0 and plain[50][2].v_y_std > 5.0


def test_the_paper_differencing_makes_no_spike_at_a_switch() -> None:
    n = _switch_frames(50, 0.75, 1.0)
    rows = _run(["car"] * 50 + ["truck"] * 60, TRUCK, velocity="difference")
    assert all(st.v_y == pytest.approx(-5.0 * st.d_y / d, rel=0.03) for _, d, st, _ in rows[1:])
    assert rows[50 + n - 1][2].v_y == pytest.approx(-5.0, rel=0.03)
    plain = _run(["car"] * 50 + ["truck"] * 60, TRUCK, velocity="difference", kind_memory_s=None)
    assert plain[50][2].v_y > 100.0                  # the distance's jump read as motion


def test_a_real_jump_still_restarts() -> None:
    """The box moving to another vehicle 20 m nearer restarts the filter with per-track kinds too."""
    est = StateEstimator(CAM, size_prior=True, contact_offset_m=0.0, kind_memory_s=1.0)
    for k in range(30):
        t = k * DT
        d = 45.0 - 5.0 * t if k < 20 else 20.0
        st = est.update([Track(id=0, box=_box(d, CAR), label="car")], t)[0]
        assert st.age_s == pytest.approx(t if k < 20 else t - 20 * DT)


def test_track_kinds_votes() -> None:
    kinds = TrackKinds(memory_s=1.0, switch_share=0.75)
    assert kinds.update([0, 1], ["Truck", "car"], [0.5, 0.9], [True, True], 0.0) == ["truck", "car"]
    assert kinds.kind == {0: "truck", 1: "car"}      # a first label is the kind at once
    # a young track: its one vote is outweighed within a few frames (closed form: n = 3 at 25 frames/s)
    got = [kinds.update([0], ["car"], [0.5], [True], k * DT)[0] for k in range(1, 4)]
    assert got == ["truck", "truck", "car"] == ["truck"] * (_switch_frames(1, 0.75, 1.0) - 1) + ["car"]
    assert kinds.kind[0] == "truck"                  # a proposal until committed
    kinds.commit(0, "car")
    assert kinds.proposal(0) == "car"
    # coasting frames do not vote
    for k in range(1, 100):
        kinds.update([1], ["bus"], [0.9], [False], k * DT)
    assert kinds.votes[1] == {"car": 0.9} and kinds.proposal(1) == "car"
    kinds.forget(1)
    assert 1 not in kinds.kind
    with pytest.raises(ValueError):
        TrackKinds(switch_share=0.5)


def test_the_window_is_in_seconds() -> None:
    """The same persistent change at 10 and 50 frames/s switches within one frame interval of the same time."""
    times = []
    for fps in (10.0, 50.0):
        kinds = TrackKinds(memory_s=0.5, switch_share=0.75)
        t, k = 0.0, 0
        while True:
            t = k / fps
            lab = "car" if t < 3.0 else "van"
            if kinds.update([7], [lab], [1.0], [True], t)[0] == "van":
                break
            k += 1
        times.append(t - 3.0)
    # a long-held kind: memory_s ln(1 / (1 - share)) = 0.69 s, to within a frame
    assert times[0] == pytest.approx(0.5 * math.log(4.0), abs=0.1)
    assert times[1] == pytest.approx(0.5 * math.log(4.0), abs=0.02)


def test_single_images_read_as_each_box_label() -> None:
    """A new track's kind is its box's label: one image (KITTI's object frames) reads as with per-box labels."""
    tracks = [Track(id=0, box=_box(20.0, TRUCK), label="truck"), Track(id=1, box=_box(35.0, CAR), label="car"),
              Track(id=2, box=_box(12.0, CAR), label="bus")]
    voted = StateEstimator(CAM, size_prior=True, contact_offset_m=0.0, kind_memory_s=1.0).update(tracks, 0.0)
    per_box = StateEstimator(CAM, size_prior=True, contact_offset_m=0.0, kind_memory_s=None).update(tracks, 0.0)
    assert voted == per_box
    assert voted[2].d_y > 1.3 * 12.0                  # the car's box labelled bus is read with the bus's prior


@pytest.mark.parametrize("kw", [{"kind_memory_s": 0.0}, {"kind_switch_share": 0.5}, {"kind_switch_share": 1.2}])
def test_bad_kind_settings_are_refused(kw) -> None:
    with pytest.raises(StateConfigError, match=next(iter(kw))):
        StateEstimator(CAM, size_prior=True, **kw)


def test_off_without_the_size_prior() -> None:
    """The size prior off (rendered frames): no kinds, and the labels' flips change nothing."""
    flips = [StateEstimator(CAM, kind_memory_s=1.0), StateEstimator(CAM, kind_memory_s=None)]
    for k, lab in enumerate(["car", "truck", "bus"] * 5):
        states = [est.update([Track(id=0, box=_box(30.0 - k * 0.2, CAR), label=lab)], k * DT) for est in flips]
        assert states[0] == states[1]
    assert flips[0].track_kind(0) is None and states[0][0].age_s == pytest.approx(14 * DT)
