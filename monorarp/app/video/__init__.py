"""The pipeline on real video: frame sources, the ``monorarp video`` run, horizon calibration, mp4 writing.

* :mod:`.source` -- :class:`VideoSource`: frames and container timestamps from a file, or a webcam;
* :mod:`.run` -- :func:`run_video`: pipeline over a source -> ``predictions.jsonl``, ``annotated.mp4``;
* :mod:`.horizon` -- :func:`estimate_horizon`: horizon row / pitch from the lane lines' vanishing point;
* :mod:`.writer` -- :class:`VideoWriter` (H.264 mp4) and :func:`read_video`;
* :mod:`.cli` -- the ``video`` and ``calibrate-horizon`` sub-commands.
"""
