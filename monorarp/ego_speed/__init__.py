"""Ego-speed estimators from dashed lane markings of known dimensions (the paper's section VI-A).

Every estimator is built as ``Cls(camera, stripe_length_m=3.05, period_m=12.19, ...)``
and fed frames with ``update(image_bgr, t) -> float | None`` (ego speed in m/s,
None while it has no valid estimate; ``t`` is the frame's timestamp in s) and
``reset()``. Registered under the kind ``ego_speed``:

* ``ground_track`` (the commands' default, :data:`monorarp.app.options.CLI_EGO_SPEED`): stripe
  ends tracked on the ground plane (:mod:`.ground_track`);
* ``lsd_period``: the paper's method, LSD lane lines and the time between
  successive dash appearances at a fixed point (:mod:`.lsd_period`).
"""
