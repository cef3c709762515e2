"""Scoring on real labelled data: ``monorarp eval kitti DIR`` (KITTI object or tracking datasets).

* :mod:`harness.kitti_eval.reader` — the dataset's files (labels, calibration, layout), checked;
* :mod:`harness.kitti_eval.geometry` — the maths: camera from the calibration, rear-face distance of a label;
* :mod:`harness.kitti_eval.cameras` — a camera per calibration and image size; the export's manifest;
* :mod:`harness.kitti_eval.truth` — labels -> scored truth (which count, distances, velocities);
* :mod:`harness.kitti_eval.run` — the pipeline over the dataset's frames;
* :mod:`harness.kitti_eval.score` — the run scoring + KITTI AP, the per-object rows;
* :mod:`harness.kitti_eval.evaluate` — orchestration (:func:`~harness.kitti_eval.evaluate.evaluate_kitti`),
  written atomically; its options: :mod:`harness.kitti_eval.options`.

The AP maths and KITTI's difficulty levels are :mod:`harness.scoring.kitti_ap` and
:mod:`harness.scoring.kitti_difficulty`. Nothing inside :mod:`monorarp` knows about KITTI.
"""
