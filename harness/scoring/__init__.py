"""Scoring of pipeline outputs against ground truth (simulated, or a labelled dataset's).

* ``evaluate`` — orchestration: a run's truths and results -> ``metrics.json`` and its records;
* ``rules`` — :class:`~harness.scoring.rules.EvalConfig` and which objects and predictions count;
* ``match`` (per-frame IoU assignment), ``pairing`` (one frame's truth and tracks side by side),
  ``records`` (per-object rows, ``per_object.csv``), ``per_frame`` (``per_frame.csv``);
* one module per metric family: ``state_errors``, ``ttc_warnings``, ``tracking`` (with ``mot``,
  ``hota``), ``detection``, ``lane_speed``, ``risk``, ``warnings`` (episodes), ``runtime``, ``horizon``;
* ``algo`` (pure maths), ``bootstrap`` (intervals over sequences), ``tables`` (printable summary and
  the paper's Table II), ``kitti_ap`` and ``kitti_difficulty`` (KITTI's AP and difficulty levels).
"""
