"""Typed per-frame, per-object records: estimate and truth side by side (``per_object.csv``).

One record per ground-truth object present in a frame (matched or not, counted
or ignored) and one per track matched to no object. Units: m, m/s, s, px.
Ego-frame naming: the truth's ``d_long``/``d_lat``/``v_long``/``v_lat`` are
compared with the estimate's ``d_y``/``d_x``/``v_y``/``v_x``.
"""

from __future__ import annotations

import csv
import math
from dataclasses import asdict, dataclass, fields
from pathlib import Path

NAN = float("nan")


@dataclass
class ObjectRecord:
    frame: int
    t: float
    gt_id: int | None = None
    track_id: int | None = None
    counted: bool = False        # GT object inside the scoring rule (visibility, range)
    matched: bool = False        # GT object and track matched (IoU >= min_iou)
    set_aside: bool = False      # unmatched track not counted as a false positive (see rules)
    iou: float = NAN
    visibility: float = NAN
    coasting: bool | None = None
    d_long_gt: float = NAN
    d_y_est: float = NAN
    d_lat_gt: float = NAN
    d_x_est: float = NAN
    v_long_gt: float = NAN
    v_y_est: float = NAN
    v_lat_gt: float = NAN
    v_x_est: float = NAN
    ttc_gt: float = NAN          # NaN: no collision within the horizon
    ttc_est: float = NAN
    gt_x1: float = NAN
    gt_y1: float = NAN
    gt_x2: float = NAN
    gt_y2: float = NAN
    est_x1: float = NAN
    est_y1: float = NAN
    est_x2: float = NAN
    est_y2: float = NAN
    d_y_std: float = NAN         # the estimator's one-sigma uncertainties (NaN: it gives none)
    d_x_std: float = NAN
    v_y_std: float = NAN
    v_x_std: float = NAN
    a_y_est: float = NAN         # relative longitudinal acceleration (m/s^2) and its one-sigma, where estimated
    a_y_std: float = NAN
    age_s: float = NAN           # time since the estimator's filter of the track started (s)
    expansion_rate: float = NAN  # the box's looming rate, closing speed / distance (1/s), where estimated
    expansion_rate_std: float = NAN
    registered_rate: float = NAN  # the same rate from registering the vehicle's patch between frames (1/s)
    registered_rate_std: float = NAN
    registered_v_x: float = NAN   # lateral velocity from the same patches' shift (m/s)
    registered_v_x_std: float = NAN

    @property
    def is_false_track(self) -> bool:
        return self.gt_id is None


COLUMNS = [f.name for f in fields(ObjectRecord)]


def as_float(v) -> float:
    """``v`` as a float; NaN for None (a record's missing value)."""
    return NAN if v is None else float(v)


def cell(v) -> str:
    """One CSV cell: empty for None or NaN, 1/0 for a bool, a float rounded to 6 digits."""
    if v is None:
        return ""
    if isinstance(v, bool):
        return "1" if v else "0"
    if isinstance(v, float):
        return "" if math.isnan(v) else repr(round(v, 6))
    return str(v)


def write_csv(records: list[ObjectRecord], path: str | Path) -> None:
    """Write records as CSV (empty cell = missing / NaN)."""
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(COLUMNS)
        for r in records:
            d = asdict(r)
            w.writerow([cell(d[c]) for c in COLUMNS])


def read_csv(path: str | Path) -> list[ObjectRecord]:
    """Inverse of :func:`write_csv`."""
    types = {f.name: f.type for f in fields(ObjectRecord)}
    out = []
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            kw = {}
            for k, v in row.items():
                t = types[k]
                if "bool" in t:
                    kw[k] = None if v == "" else v == "1"
                elif t.startswith("int"):
                    kw[k] = None if v == "" else int(v)
                else:
                    kw[k] = NAN if v == "" else float(v)
            out.append(ObjectRecord(**kw))
    return out
