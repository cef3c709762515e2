"""The warning stage's settings: one typed record, keyword overrides, one-line errors naming the field."""

from __future__ import annotations

import copy

import pytest

from monorarp.core.camera import CameraModel
from monorarp.core.errors import UserError
from monorarp.core.types import ObjectState
from monorarp.warning.config import WarningConfig, WarningConfigError, warning_config
from monorarp.warning.fcw import ForwardCollisionWarning
from monorarp.warning.thresholds import FCW_THRESHOLD_S


def test_defaults_overrides_and_config_agree():
    assert ForwardCollisionWarning().config == WarningConfig()
    assert WarningConfig().ttc_threshold_s == FCW_THRESHOLD_S
    cfg = WarningConfig(hold_s=0.5, accel_sigmas=None)
    w = ForwardCollisionWarning(config=cfg, min_on_s=0.2)          # overrides on top of the given config
    assert (w.config.hold_s, w.config.accel_sigmas, w.config.min_on_s) == (0.5, None, 0.2)
    assert cfg.min_on_s == 0.1                                    # the given record is not changed
    assert ForwardCollisionWarning(ttc_threshold_s=3).config.ttc_threshold_s == 3.0      # ints become floats
    with pytest.raises(Exception):
        w.config.hold_s = 2.0                                     # frozen: settings change only by validation
    # every field has a one-line description
    assert all(f.description and "\n" not in f.description for f in WarningConfig.model_fields.values())


def test_settings_keep_their_keyword_names_through_the_registry():
    from monorarp.pipeline import registry

    w = registry.build("warning", "fcw", {"hold_s": 0.25, "looming_sigmas": None})
    assert isinstance(w, ForwardCollisionWarning) and w.config.hold_s == 0.25 and w.config.looming_sigmas is None


@pytest.mark.parametrize("kw,name", [({"ttc_threshold_s": -1.0}, "ttc_threshold_s"),
                                     ({"hold_s": float("inf")}, "hold_s"), ({"looming_share": 2.0}, "looming_share"),
                                     ({"accel_sigmas": "x"}, "accel_sigmas"),
                                     ({"distance_sigmas": float("nan")}, "distance_sigmas"), ({"hold": 1.0}, "hold")])
def test_a_bad_setting_is_one_line_naming_it(kw, name):
    with pytest.raises(WarningConfigError) as e:
        ForwardCollisionWarning(**kw)
    assert isinstance(e.value, UserError) and isinstance(e.value, ValueError)
    assert name in str(e.value) and "\n" not in str(e.value)
    with pytest.raises(WarningConfigError):
        warning_config(None, kw)


def test_the_camera_sets_the_offsets_and_the_threshold_can_be_raised():
    cam = CameraModel(fx=800.0, fy=800.0, cx=320.0, cy=180.0, width=640, height=360, height_m=1.3,
                      forward_offset_m=1.5, lateral_offset_m=0.2)
    w = ForwardCollisionWarning(camera=cam, camera_forward_offset_m=9.0)
    assert (w.config.camera_forward_offset_m, w.config.camera_lateral_offset_m) == (1.5, 0.2)
    lead = {1: ObjectState(1, 0.0, 40.0, 0.0, -10.0)}             # 4 s away: beyond the default 3 s
    assert w.threats(lead) == {}
    raised = copy.copy(w)
    raised.ttc_threshold_s = 10.0
    assert 1 in raised.threats(lead) and w.ttc_threshold_s == FCW_THRESHOLD_S
    with pytest.raises(WarningConfigError, match="ttc_threshold_s"):
        raised.ttc_threshold_s = 0.0
