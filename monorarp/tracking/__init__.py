"""Trackers: detections in, boxes with stable ids out (the paper's section IV-B).

Built-in trackers (kind ``"tracker"``, declared in :mod:`monorarp.pipeline.catalogue`): ``particle``
(the paper's, :mod:`.particle`), ``kcf``, ``csrt``, ``mosse``, ``medianflow`` (OpenCV,
:mod:`.opencv`), ``sort`` (:mod:`.sort`) and ``bytetrack`` (:mod:`.bytetrack`).
"""
