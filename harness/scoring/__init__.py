"""Scoring of pipeline outputs against simulation ground truth.

``match`` (per-frame IoU assignment), ``algo`` (pure maths), ``mot`` (motmetrics),
``records`` (per-object rows), ``evaluate`` (orchestration, ``metrics.json``),
``tables`` (printable summary and the paper's Table II).
"""
