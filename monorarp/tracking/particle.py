"""The paper's particle tracker (section IV-B) with its tracker control.

Per track, ``N`` particles over the box state ``(cx, cy, w, h)`` (pixels), all tracks in one
``(T, N, 4)`` array: predict (box velocity in px/s x frame interval from timestamps), associate
(Hungarian on ``1 - IoU``), update, resample. Tracker control (confirmation, coasting, lost
tracks, re-identification), suppressed outputs and the output box: docs/tracking.md.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from monorarp.core.boxes import intersection, iou_matrix
from monorarp.tracking.appearance import BINS, bhattacharyya, colour_histograms
from monorarp.tracking.association import assign, associate_iou
from monorarp.tracking.bookkeeping import BookTracker, TrackBook, detections_array
from monorarp.core.types import Detection, Track

_MIN_SIZE = 1.0  # px: particles never shrink a box below this
_APP_RATE = 0.3         # appearance update weight, once a track has averaged 1 / _APP_RATE detections
_REID_SIZE = 1.6        # re-identification: box heights within this ratio


def boxes_to_cxcywh(boxes: np.ndarray) -> np.ndarray:
    """(..., 4) (x1, y1, x2, y2) -> (..., 4) (cx, cy, w, h)."""
    b = np.asarray(boxes, dtype=float)
    return np.stack([(b[..., 0] + b[..., 2]) / 2, (b[..., 1] + b[..., 3]) / 2,
                     b[..., 2] - b[..., 0], b[..., 3] - b[..., 1]], axis=-1)


def cxcywh_to_boxes(s: np.ndarray) -> np.ndarray:
    """(..., 4) (cx, cy, w, h) -> (..., 4) (x1, y1, x2, y2)."""
    s = np.asarray(s, dtype=float)
    hw, hh = s[..., 2] / 2, s[..., 3] / 2
    return np.stack([s[..., 0] - hw, s[..., 1] - hh, s[..., 0] + hw, s[..., 1] + hh], axis=-1)


def systematic_resample(weights: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """(T, N) normalised weights -> (T, N) particle indices, one systematic draw per row."""
    n_t, n = weights.shape
    cdf = np.cumsum(weights, axis=1)
    cdf[:, -1] = 1.0  # guard against round-off
    positions = (rng.random((n_t, 1)) + np.arange(n)[None, :]) / n
    # Search every row at once: offset row r's values by r so rows never interleave.
    offsets = np.arange(n_t)[:, None]
    idx = np.searchsorted((cdf + offsets).ravel(), (positions + offsets).ravel(), side="left")
    return np.minimum(idx.reshape(n_t, n) - offsets * n, n - 1)


def fit_velocity(z: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Least-squares slope of (T, K, 4) boxes ``z`` against (T, K) times ``t`` -> (T, 4) per second.

    NaN times mark empty slots (their ``z`` must be finite); a row with fewer than two
    distinct times gets velocity 0.
    """
    valid = ~np.isnan(t)
    t = np.where(valid, t, 0.0)
    t_mean = t.sum(axis=1) / np.maximum(valid.sum(axis=1), 1)
    dt = np.where(valid, t - t_mean[:, None], 0.0)                       # sums to 0 over each row
    num = np.einsum("tk,tkc->tc", dt, z)                                 # = sum dt (z - mean z)
    den = np.einsum("tk,tk->t", dt, dt)
    return np.where(den[:, None] > 0, num / np.where(den > 0, den, 1.0)[:, None], 0.0)


def _indices(parts: list[np.ndarray]) -> np.ndarray:
    """Index arrays joined into one int array (empty when there are none)."""
    return np.concatenate(parts).astype(int) if parts else np.empty(0, dtype=int)


class ParticleTracker(BookTracker):
    """Multi-object particle tracker; ``update(image, detections, t) -> list[Track]``.

    Parameters (noise scales are fractions of the box's width/height):
        n_particles: particles per track.
        pos_noise, size_noise: process noise std of the centre and of the size.
        meas_noise: measurement std of the detection likelihood.
        min_iou: association gate (IoU between predicted box and detection).
        min_hits: matched frames before a track is confirmed and output.
        max_coast: missed frames a confirmed track is still output (coasting).
        max_lost: missed frames a confirmed track is kept (not output after ``max_coast``)
            for re-identification; deleted after ``max(max_coast, max_lost)`` misses.
        vel_window: matched detections (>= 2) the box velocity is fitted to.
        edge_px: a last detection this close (px) to the left/right border, moving outwards,
            marks a track leaving the view (not output while coasting); negative: off.
        occluded_cover, duplicate_cover: a coasting box covered this much by a nearer / a
            not nearer detection of this frame is not output (module docstring; > 1: off).
        spawn_iou: a detection with this IoU with a matched detection starts no track (> 1: off).
        min_score: detections below this score are weak, as those the detector marks ``weak``
            (under its decision threshold): they never start a track and only extend tracks that
            no strong detection matched (a second association pass, as ByteTrack's).
        box_output: ``"detection"`` or ``"mean"`` (see module docstring).
        reid_distance: re-identify a lost track with a new detection whose colour appearance is
            within this Bhattacharyya distance of the track's and whose box is near its last one
            (docs/tracking.md, re-identification by appearance); ``None``: off.
        reid_gate: the re-identification's reach: centres at most this many box widths apart.
        seed: RNG seed (results are deterministic for a given seed).
    """

    uses_seed = True     # a sweep passes the run's seed
    uses_weak_detections = True   # the pipeline gives it the detector's weak detections too

    def __init__(self, n_particles: int = 100, pos_noise: float = 0.03, size_noise: float = 0.02,
                 meas_noise: float = 0.05, min_iou: float = 0.2, min_hits: int = 2, max_coast: int = 10,
                 min_score: float = 0.0, box_output: str = "detection", seed: int = 0, max_lost: int = 60,
                 vel_window: int = 10, edge_px: float = 4.0, occluded_cover: float = 0.9,
                 duplicate_cover: float = 0.5, spawn_iou: float = 0.5, reid_distance: float | None = 0.5,
                 reid_gate: float = 2.5) -> None:
        if n_particles < 1:
            raise ValueError(f"n_particles must be >= 1, got {n_particles}")
        if box_output not in ("detection", "mean"):
            raise ValueError(f"box_output must be 'detection' or 'mean', got {box_output!r}")
        if min_hits < 1 or max_coast < 0 or max_lost < 0:
            raise ValueError(f"need min_hits >= 1, max_coast >= 0 and max_lost >= 0, "
                             f"got {min_hits}, {max_coast}, {max_lost}")
        if vel_window < 2:
            raise ValueError(f"vel_window must be >= 2, got {vel_window}")
        if reid_distance is not None and not 0 < reid_distance <= 1:
            raise ValueError(f"reid_distance must be in (0, 1] or null (off), got {reid_distance}")
        if reid_gate <= 0:
            raise ValueError(f"reid_gate must be > 0, got {reid_gate}")
        self.n_particles = int(n_particles)
        self.noise_scale = np.array([pos_noise, pos_noise, size_noise, size_noise], dtype=float)
        self.meas_noise = float(meas_noise)
        self.min_iou = float(min_iou)
        self.min_hits = int(min_hits)
        self.max_coast = int(max_coast)
        self.max_lost = int(max_lost)
        self.vel_window = int(vel_window)
        self.edge_px = float(edge_px)
        self.occluded_cover = float(occluded_cover)
        self.duplicate_cover = float(duplicate_cover)
        self.spawn_iou = float(spawn_iou)
        self.min_score = float(min_score)
        self.box_output = box_output
        self.reid_distance = None if reid_distance is None else float(reid_distance)
        self.reid_gate = float(reid_gate)
        self.seed = seed
        self.reset()

    # ------------------------------------------------------------------ state
    def reset(self) -> None:
        """Forget every track; ids start again from 0; the RNG is re-seeded."""
        self._rng = np.random.default_rng(self.seed)
        n, w, f = self.n_particles, self.vel_window, np.float64
        self._book = TrackBook(
            particles=((n, 4), f),      # (T, N, 4) cx, cy, w, h
            mean=((4,), f),             # posterior mean per track
            vel=((4,), f),              # box velocity per track (px/s)
            out=((4,), f),              # output box (x1, y1, x2, y2)
            hits=((), np.int64), misses=((), np.int64),
            weak_hit=((), bool),        # last matched detection was weak (output as coasting: no measurement)
            last_det=((4,), f),         # last matched detection box (x1, y1, x2, y2)
            hist=((w, 4), f),           # last matched detections (cxcywh), ring buffer
            hist_t=((w,), f),           # their frame times (NaN: empty slot)
            app=((int(np.prod(BINS)),), f),  # colour appearance (appearance.colour_histograms)
            app_n=((), np.int64))       # detections it averages (0: none yet)
        self._t_last: float | None = None

    # ---------------------------------------------------------------- stages
    def _predict(self, dt: float) -> None:
        """Move every particle by its track's velocity * dt plus size-relative Gaussian noise."""
        if not self.n_tracks:
            return
        sizes = np.maximum(self._book.mean[:, [2, 3, 2, 3]], _MIN_SIZE)           # (T, 4)
        noise = self._rng.standard_normal(self._book.particles.shape) * (sizes * self.noise_scale)[:, None, :]
        self._book.particles = self._book.particles + (self._book.vel * dt)[:, None, :] + noise
        self._book.particles[..., 2:] = np.maximum(self._book.particles[..., 2:], _MIN_SIZE)
        self._book.mean = self._book.particles.mean(axis=1)

    def _update(self, rows: np.ndarray, z: np.ndarray) -> None:
        """Weight, average and resample the particles of tracks ``rows`` given detections ``z`` (cxcywh)."""
        p = self._book.particles[rows]                                            # (M, N, 4)
        sigma = np.maximum(z[:, [2, 3, 2, 3]], _MIN_SIZE) * self.meas_noise  # (M, 4)
        loglik = -0.5 * np.sum(((p - z[:, None, :]) / sigma[:, None, :]) ** 2, axis=2)
        w = np.exp(loglik - loglik.max(axis=1, keepdims=True))
        w /= w.sum(axis=1, keepdims=True)
        new_mean = np.einsum("mn,mnk->mk", w, p)
        idx = systematic_resample(w, self._rng)
        resampled = p[np.arange(len(rows))[:, None], idx]                   # fancy indexing: a new array
        self._book.particles[rows] = resampled
        self._book.mean[rows] = new_mean
        # Velocity: least-squares slope of the last vel_window matched detections against frame time.
        # Ring buffer: hit number h (0 = the spawning detection) goes to slot h % vel_window; the fit
        # does not depend on the order of the slots.
        slot = self._book.hits[rows] % self.vel_window
        self._book.hist[rows, slot], self._book.hist_t[rows, slot] = z, self._t_last
        self._book.vel[rows] = fit_velocity(self._book.hist[rows], self._book.hist_t[rows])

    def _particles_at(self, z: np.ndarray) -> np.ndarray:
        """(K, N, 4) fresh particles around boxes ``z`` (K, 4) cxcywh: std ``meas_noise`` x size."""
        sizes = np.maximum(z[:, [2, 3, 2, 3]], _MIN_SIZE) * self.meas_noise
        parts = z[:, None, :] + self._rng.standard_normal((len(z), self.n_particles, 4)) * sizes[:, None, :]
        parts[..., 2:] = np.maximum(parts[..., 2:], _MIN_SIZE)
        return parts

    def _spawn(self, z: np.ndarray, scores: np.ndarray, labels: list[str],
               app: np.ndarray | None = None, valid: np.ndarray | None = None) -> None:
        """Start tentative tracks at detections ``z`` (cxcywh), with their appearances when known."""
        k = len(z)
        if not k:
            return
        parts = self._particles_at(z)
        hist = np.zeros((k, self.vel_window, 4))
        hist_t = np.full((k, self.vel_window), np.nan)
        hist[:, 0], hist_t[:, 0] = z, self._t_last                    # hit 0 -> slot 0
        extra = {} if app is None else {"app": app, "app_n": valid.astype(np.int64)}
        self._book.add(scores, labels, particles=parts, mean=z, out=cxcywh_to_boxes(z), hits=1,
                       last_det=cxcywh_to_boxes(z), hist=hist, hist_t=hist_t, **extra)

    def _appearances(self, image: np.ndarray | None,
                     det_boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """Each detection's colour appearance and whether it has one (some pixel in the image);
        None when re-identification is off or there is no colour (BGR) image."""
        if self.reid_distance is None or image is None or image.ndim != 3 or not len(det_boxes):
            return None
        app = colour_histograms(image, det_boxes)
        return app, app.any(axis=1)

    def _learn_appearance(self, rows: np.ndarray, app: np.ndarray, valid: np.ndarray) -> None:
        """Running average of the appearances of tracks ``rows`` with their detections' ``app`` (``valid`` ones)."""
        rows, app = rows[valid], app[valid]
        n = self._book.app_n[rows]
        rate = np.maximum(_APP_RATE, 1.0 / (n + 1))[:, None]
        self._book.app[rows] = (1 - rate) * self._book.app[rows] + rate * app
        self._book.app_n[rows] = n + 1

    def _reidentify(self, rows: np.ndarray, cols: np.ndarray, free: np.ndarray, det_boxes: np.ndarray,
                    app: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pair lost tracks with the ``free`` (unmatched strong) detections by appearance.

        A pair needs box heights within ``_REID_SIZE``, bottom edges within half the track's last
        height (+2 px), centres within ``reid_gate`` box widths, and an appearance distance of at
        most ``reid_distance``; the pairs minimise the total distance. Returns ``(rows, cols, free)``
        with the pairs added.
        """
        book = self._book
        taken = np.zeros(self.n_tracks, dtype=bool)
        taken[rows] = True
        lost = np.flatnonzero(~taken & (book.misses > self.max_coast) & (book.app_n > 0))
        if not len(lost) or not len(free):
            return rows, cols, free
        last, det = book.last_det[lost], det_boxes[free]
        lw, lh = last[:, 2] - last[:, 0], last[:, 3] - last[:, 1]
        dw, dh = det[:, 2] - det[:, 0], det[:, 3] - det[:, 1]
        ratio = dh[None, :] / np.maximum(lh[:, None], 1e-9)
        dx = np.abs((det[None, :, 0] + det[None, :, 2]) - (last[:, None, 0] + last[:, None, 2])) / 2
        near = ((ratio <= _REID_SIZE) & (ratio >= 1 / _REID_SIZE)
                & (np.abs(det[None, :, 3] - last[:, None, 3]) <= 0.5 * lh[:, None] + 2.0)
                & (dx <= self.reid_gate * np.maximum(lw[:, None], dw[None, :])))
        cost = np.where(near, bhattacharyya(book.app[lost], app[free]), np.inf)
        m, _, _ = assign(cost, self.reid_distance)
        if not len(m):
            return rows, cols, free
        t, d = lost[m[:, 0]], free[m[:, 1]]
        return np.concatenate([rows, t]), np.concatenate([cols, d]), np.setdiff1d(free, d)

    def _restart(self, rows: np.ndarray, boxes: np.ndarray) -> None:
        """Tracks ``rows`` found again after being lost forget their motion: particles restart at
        ``boxes`` (x1, y1, x2, y2), with no velocity and no velocity history."""
        z = boxes_to_cxcywh(boxes)
        book = self._book
        book.particles[rows], book.mean[rows], book.vel[rows] = self._particles_at(z), z, 0.0
        book.hist_t[rows] = np.nan

    def _leaving(self, width: int) -> np.ndarray:
        """Tracks whose last detection touched the left/right image border while moving outwards."""
        b, vx = self._book.last_det, self._book.vel[:, 0]
        left = (b[:, 0] <= -0.5 + self.edge_px) & (vx < 0)
        right = (b[:, 2] >= width - 0.5 - self.edge_px) & (vx > 0)
        return left | right

    def _covered(self, boxes: np.ndarray, det_boxes: np.ndarray) -> np.ndarray:
        """Which coasting ``boxes`` lie on a vehicle detected this frame (so are not output).

        Covered by a nearer detection (its bottom edge lower in the image) by at least
        ``occluded_cover`` of their area: hidden behind it, so not visible either way. Covered
        by a detection not nearer by at least ``duplicate_cover``: were the track's vehicle
        there, it would hide that farther one and be detected itself; the track is more likely
        a duplicate or a part of that vehicle (a truck's lower half, a car's window).
        """
        inter = intersection(boxes[:, None, :], det_boxes[None, :, :])
        area = np.maximum((boxes[:, 2] - boxes[:, 0]) * (boxes[:, 3] - boxes[:, 1]), 1e-9)
        cover = inter / area[:, None]
        nearer = det_boxes[None, :, 3] > boxes[:, None, 3]
        return ((np.where(nearer, cover, 0.0).max(axis=1) >= self.occluded_cover)
                | (np.where(nearer, 0.0, cover).max(axis=1) >= self.duplicate_cover))

    def _associate(self, pred: np.ndarray, det_boxes: np.ndarray,
                   strong: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Match tracks to detections in passes; return (track rows, detection indices, unmatched strong ones).

        Active tracks (tentative, tracked, coasting) first, then lost ones, each time on the
        ``strong`` detections; then the weak ones on the tracks still unmatched, in the same order
        (ByteTrack's second pass: a weak detection extends a track, never displaces a strong one,
        never starts one). With no weak detection the last two passes have nothing to do.
        """
        active = np.flatnonzero(self._book.misses <= self.max_coast)
        lost = np.flatnonzero(self._book.misses > self.max_coast)
        free_t = np.ones(len(pred), dtype=bool)
        free_d = np.ones(len(det_boxes), dtype=bool)
        rows, cols = [], []
        for tracks, dets in ((active, strong), (lost, strong), (active, ~strong), (lost, ~strong)):
            t_idx, d_idx = tracks[free_t[tracks]], np.flatnonzero(dets & free_d)
            if not len(t_idx) or not len(d_idx):
                continue
            m, _, _, _ = associate_iou(pred[t_idx], det_boxes[d_idx], self.min_iou)
            rows.append(t_idx[m[:, 0]])
            cols.append(d_idx[m[:, 1]])
            free_t[rows[-1]], free_d[cols[-1]] = False, False
        return _indices(rows), _indices(cols), np.flatnonzero(strong & free_d)

    # ------------------------------------------------------------------ API
    def update(self, image: np.ndarray | None, detections: Sequence[Detection], t: float) -> list[Track]:
        """Advance to frame time ``t`` (s) with this frame's detections; return the output tracks.

        The tracker follows detections; ``image`` (Table I's interface, shared with
        image-based trackers) gives its width, for the leaving-the-view rule, and the
        detections' colours, for re-identification (``None``: both are off).
        """
        dt = 0.0 if self._t_last is None else float(t) - self._t_last
        self._t_last = float(t)
        book = self._book
        book.step()
        n_det = len(detections)
        det_boxes, det_scores = detections_array(detections)

        self._predict(dt)
        pred = cxcywh_to_boxes(book.mean)
        strong = (det_scores >= self.min_score) & ~np.array([d.weak for d in detections], dtype=bool)
        rows, cols, un_d = self._associate(pred, det_boxes, strong)
        looks = self._appearances(image, det_boxes)
        if looks is not None:
            rows, cols, un_d = self._reidentify(rows, cols, un_d, det_boxes, looks[0])
        back = book.misses[rows] > self.max_coast      # lost tracks found again, by overlap or colour
        if back.any():
            self._restart(rows[back], det_boxes[cols[back]])
        matched = np.zeros(self.n_tracks, dtype=bool)
        matched[rows] = True
        if len(rows):
            z = boxes_to_cxcywh(det_boxes[cols])
            self._update(rows, z)
            book.out[rows] = (det_boxes[cols] if self.box_output == "detection"
                              else cxcywh_to_boxes(book.mean[rows]))
            book.last_det[rows] = det_boxes[cols]
            book.weak_hit[rows] = ~strong[cols]
            book.hit(rows, det_scores[cols], [detections[c].label for c in cols])
            if looks is not None:
                self._learn_appearance(rows, looks[0][cols], looks[1][cols] & strong[cols])
        coast = ~matched
        book.out[coast] = cxcywh_to_boxes(book.mean[coast])
        book.hits[matched] += 1
        book.misses[matched] = 0
        book.misses[coast] += 1

        confirmed = book.hits >= self.min_hits
        alive = np.where(confirmed, book.misses <= max(self.max_coast, self.max_lost), book.misses == 0)
        if not alive.all():
            book.keep(alive)

        new = un_d
        if len(new) and len(cols):
            # A second box on a vehicle a track already holds this frame starts no track.
            new = new[iou_matrix(det_boxes[new], det_boxes[cols]).max(axis=1) < self.spawn_iou]
        if len(new):
            self._spawn(boxes_to_cxcywh(det_boxes[new]), det_scores[new], [detections[i].label for i in new],
                        *((looks[0][new], looks[1][new]) if looks is not None else ()))

        show = ((book.hits >= self.min_hits) | book.early(self.min_hits)) & (book.misses <= self.max_coast)
        if image is not None and self.edge_px >= 0:
            show &= (book.misses == 0) | ~self._leaving(image.shape[1])
        hide = show & (book.misses > 0)
        if hide.any() and n_det:
            show[hide] = ~self._covered(book.out[hide], det_boxes)
        weak_only = show & (book.misses == 0) & book.weak_hit
        if weak_only.any() and strong.any():
            # A track only a weak box supports is judged against the strong boxes (not its own).
            show[weak_only] = ~self._covered(book.out[weak_only], det_boxes[strong])
        rows = np.flatnonzero(show)
        return book.tracks(rows, book.out[rows], coasting=(book.misses[rows] > 0) | book.weak_hit[rows])
