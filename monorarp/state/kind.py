"""Per-track vehicle kind for the size prior: the detector's class labels voted over time, with hysteresis.

A detector may flip one vehicle's label from frame to frame (yolox on a real SUV: car, truck, bus), and each kind
puts the size prior's distance elsewhere (at 25 m: 20.6, 26.0, 30.9 m). Per track, each label keeps a vote: at each
frame a detection supports the track, every vote decays by ``exp(-dt / memory_s)`` (``dt`` s since the track's last
vote) and the detection's label gains its score. The track's kind is its first label; it proposes another only when
that one holds at least ``switch_share`` of the votes. An alternating or single-frame flip never gets there; a
persistent change does after ``memory_s ln(1 / (1 - switch_share))`` s on a long-held track (1.4 s at 1 s, 0.75),
within a few frames on a young one (its votes are few). Labels compare case-insensitively.
"""

from __future__ import annotations

import math
from collections.abc import Sequence


class TrackKinds:
    """Per track id: decayed score-weighted votes per label (``votes``) and the kind in use (``kind``).

    :meth:`update` votes and returns each track's proposed kind; :meth:`commit` makes one the track's kind (the
    caller decides when a proposal takes effect: the state estimator re-expresses the track's filter first).
    """

    def __init__(self, memory_s: float = 1.0, switch_share: float = 0.75) -> None:
        if not memory_s > 0 or not 0.5 < switch_share <= 1.0:
            raise ValueError(f"need memory_s > 0 and 0.5 < switch_share <= 1, got {memory_s}, {switch_share}")
        self.memory_s, self.switch_share = float(memory_s), float(switch_share)
        self.reset()

    def reset(self) -> None:
        """Forget every track."""
        self.votes: dict[int, dict[str, float]] = {}
        self.kind: dict[int, str] = {}
        self._t: dict[int, float] = {}

    def forget(self, track_id: int) -> None:
        """Forget one track."""
        self.votes.pop(track_id, None)
        self.kind.pop(track_id, None)
        self._t.pop(track_id, None)

    def update(self, ids: Sequence[int], labels: Sequence[str], scores: Sequence[float], supported: Sequence[bool],
               t: float) -> list[str]:
        """Vote at frame time ``t`` (s) and return each track's proposed kind (lower case).

        Tracks ``supported`` (a detection this frame, not coasting) vote their label with weight ``scores`` (a
        non-finite or non-positive score counts as 1e-3); a track's first label becomes its kind at once. The
        proposal is the kind in use unless another label holds ``switch_share`` of the track's votes."""
        out = []
        for i, lab, s, sup in zip(ids, labels, scores, supported):
            lab = str(lab).lower()
            if i not in self.kind:
                self.kind[i], self.votes[i], self._t[i] = lab, {}, t
            if sup:
                v = self.votes[i]
                decay = math.exp(-max(t - self._t[i], 0.0) / self.memory_s)
                for k in v:
                    v[k] *= decay
                v[lab] = v.get(lab, 0.0) + (float(s) if math.isfinite(s) and s > 0 else 1e-3)
                self._t[i] = t
            out.append(self.proposal(i))
        return out

    def proposal(self, track_id: int) -> str:
        """The kind a track would switch to now: the label holding ``switch_share`` of its votes, else its kind."""
        cur, v = self.kind[track_id], self.votes.get(track_id, {})
        total = sum(v.values())
        if total > 0:
            best = max(sorted(v), key=v.__getitem__)
            if best != cur and v[best] >= self.switch_share * total:
                return best
        return cur

    def commit(self, track_id: int, kind: str) -> None:
        """Make ``kind`` the track's kind."""
        self.kind[track_id] = kind
