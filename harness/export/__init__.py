"""Dataset exports at the harness's boundary: the harness's frames and exact labels in the
field's formats (KITTI object, KITTI tracking, MOTChallenge), for ``monorarp export``.

* :mod:`harness.export.geometry` — the maths (KITTI boxes from the truth's 3-D corners,
  calibration matrices, truncation, occlusion); it says how the pitched camera is represented;
* :mod:`harness.export.kitti`, :mod:`harness.export.mot` — the text formats and writers;
* :mod:`harness.export.source` — frames from a scenario (rendered now) or a run directory;
* :mod:`harness.export.exporter` — source -> writer, written atomically.

Nothing inside :mod:`monorarp` knows about these formats.
"""
