"""A line-by-line port of KITTI's object devkit 2-D AP (kitti-object-eval-python ``eval.py``:
``clean_data``, ``compute_statistics_jit``, ``get_thresholds``, ``get_mAP``/``get_mAP_R40``), for tests only.

A different code path from :mod:`harness.scoring.kitti_ap`: ground-truth-centric matching redone at
each of up to 41 score thresholds chosen among the true positives, plain Python loops.
"""

from __future__ import annotations

import numpy as np

MIN_HEIGHT = [40, 25, 25]
MAX_OCCLUSION = [0, 1, 2]
MAX_TRUNCATION = [0.15, 0.3, 0.5]
N_SAMPLE_PTS = 41


def box_overlap(boxes, query, criterion=-1):
    n, k = len(boxes), len(query)
    out = np.zeros((n, k))
    for j in range(k):
        q_area = (query[j, 2] - query[j, 0]) * (query[j, 3] - query[j, 1])
        for i in range(n):
            iw = min(boxes[i, 2], query[j, 2]) - max(boxes[i, 0], query[j, 0])
            if iw > 0:
                ih = min(boxes[i, 3], query[j, 3]) - max(boxes[i, 1], query[j, 1])
                if ih > 0:
                    a = (boxes[i, 2] - boxes[i, 0]) * (boxes[i, 3] - boxes[i, 1])
                    ua = a + q_area - iw * ih if criterion == -1 else a
                    out[i, j] = iw * ih / ua
    return out


def clean_data(gt, dt, cls, difficulty):
    ignored_gt, ignored_dt, dc = [], [], []
    n_valid = 0
    for i, name in enumerate(gt["name"]):
        b = gt["bbox"][i]
        height = b[3] - b[1]
        name = name.lower()
        if name == cls:
            valid = 1
        elif cls == "car" and name == "van":
            valid = 0
        else:
            valid = -1
        ignore = (gt["occluded"][i] > MAX_OCCLUSION[difficulty] or gt["truncated"][i] > MAX_TRUNCATION[difficulty]
                  or height <= MIN_HEIGHT[difficulty])
        if valid == 1 and not ignore:
            ignored_gt.append(0)
            n_valid += 1
        elif valid == 0 or (ignore and valid == 1):
            ignored_gt.append(1)
        else:
            ignored_gt.append(-1)
        if gt["name"][i] == "DontCare":
            dc.append(b)
    for i, name in enumerate(dt["name"]):
        valid = 1 if name.lower() == cls else -1
        height = abs(dt["bbox"][i][3] - dt["bbox"][i][1])
        if height < MIN_HEIGHT[difficulty]:
            ignored_dt.append(1)
        elif valid == 1:
            ignored_dt.append(0)
        else:
            ignored_dt.append(-1)
    return n_valid, ignored_gt, ignored_dt, np.array(dc, dtype=float).reshape(-1, 4)


def compute_statistics(overlaps, dt_boxes, dt_scores, ignored_gt, ignored_det, dc_boxes, min_overlap, thresh=0.0,
                       compute_fp=False):
    det_size, gt_size = len(dt_scores), len(ignored_gt)
    assigned = [False] * det_size
    ignored_threshold = [bool(compute_fp and dt_scores[i] < thresh) for i in range(det_size)]
    NO_DETECTION = -10000000
    tp = fp = fn = 0
    thresholds = []
    for i in range(gt_size):
        if ignored_gt[i] == -1:
            continue
        det_idx, valid_detection, max_overlap, assigned_ignored_det = -1, NO_DETECTION, 0, False
        for j in range(det_size):
            if ignored_det[j] == -1 or assigned[j] or ignored_threshold[j]:
                continue
            overlap, score = overlaps[j, i], dt_scores[j]
            if not compute_fp and overlap > min_overlap and score > valid_detection:
                det_idx, valid_detection = j, score
            elif (compute_fp and overlap > min_overlap and (overlap > max_overlap or assigned_ignored_det)
                  and ignored_det[j] == 0):
                max_overlap, det_idx, valid_detection, assigned_ignored_det = overlap, j, 1, False
            elif compute_fp and overlap > min_overlap and valid_detection == NO_DETECTION and ignored_det[j] == 1:
                det_idx, valid_detection, assigned_ignored_det = j, 1, True
        if valid_detection == NO_DETECTION and ignored_gt[i] == 0:
            fn += 1
        elif valid_detection != NO_DETECTION and (ignored_gt[i] == 1 or ignored_det[det_idx] == 1):
            assigned[det_idx] = True
        elif valid_detection != NO_DETECTION:
            tp += 1
            thresholds.append(dt_scores[det_idx])
            assigned[det_idx] = True
    if compute_fp:
        for i in range(det_size):
            if not (assigned[i] or ignored_det[i] == -1 or ignored_det[i] == 1 or ignored_threshold[i]):
                fp += 1
        nstuff = 0
        ov_dc = box_overlap(dt_boxes, dc_boxes, 0)
        for i in range(len(dc_boxes)):
            for j in range(det_size):
                if assigned[j] or ignored_det[j] in (-1, 1) or ignored_threshold[j]:
                    continue
                if ov_dc[j, i] > min_overlap:
                    assigned[j] = True
                    nstuff += 1
        fp -= nstuff
    return tp, fp, fn, thresholds


def get_thresholds(scores, num_gt):
    scores = sorted(scores)[::-1]
    current_recall, out = 0.0, []
    for i, score in enumerate(scores):
        l_recall = (i + 1) / num_gt
        r_recall = (i + 2) / num_gt if i < len(scores) - 1 else l_recall
        if (r_recall - current_recall) < (current_recall - l_recall) and i < len(scores) - 1:
            continue
        out.append(score)
        current_recall += 1 / (N_SAMPLE_PTS - 1.0)
    return out


def devkit_ap(gts: list[dict], dts: list[dict], cls: str, difficulty: int, min_overlap: float) -> tuple[float, float]:
    """``(AP_R40, AP_R11)`` as fractions. ``gts[i]``: name, bbox (N, 4), occluded, truncated; ``dts[i]``: name,
    bbox (M, 4), score."""
    cls = cls.lower()
    prepared, all_thr, n_valid = [], [], 0
    for gt, dt in zip(gts, dts):
        nv, ig, idt, dc = clean_data(gt, dt, cls, difficulty)
        n_valid += nv
        gb, db = np.asarray(gt["bbox"], float).reshape(-1, 4), np.asarray(dt["bbox"], float).reshape(-1, 4)
        ov = box_overlap(db, gb, -1)
        sc = np.asarray(dt["score"], float)
        prepared.append((ov, db, sc, ig, idt, dc))
        all_thr += compute_statistics(ov, db, sc, ig, idt, dc, min_overlap)[3]
    if n_valid == 0:
        return float("nan"), float("nan")
    thresholds = get_thresholds(all_thr, n_valid)
    pr = np.zeros((len(thresholds), 3))
    for ov, db, sc, ig, idt, dc in prepared:
        for t, thr in enumerate(thresholds):
            tp, fp, fn, _ = compute_statistics(ov, db, sc, ig, idt, dc, min_overlap, thr, True)
            pr[t] += (tp, fp, fn)
    prec = np.zeros(N_SAMPLE_PTS)
    for i in range(len(thresholds)):
        prec[i] = pr[i, 0] / (pr[i, 0] + pr[i, 1])
    for i in range(len(thresholds)):
        prec[i] = np.max(prec[i:])
    return float(prec[1:].sum() / 40), float(prec[0::4].sum() / 11)
