"""Scoring on real labelled data: ``monorarp eval kitti DIR`` (KITTI object or tracking datasets).

* :mod:`harness.kitti_eval.reader` — the dataset's files (labels, calibration, layout), checked;
* :mod:`harness.kitti_eval.geometry` — the maths: camera from the calibration, rear-face distance of a label;
* :mod:`harness.kitti_eval.evaluate` — dataset -> pipeline -> the run scoring + KITTI AP, written atomically.

The AP maths is :mod:`harness.scoring.kitti_ap`. Nothing inside :mod:`monorarp` knows about KITTI.
"""
