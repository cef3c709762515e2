"""The state estimator's settings (monorarp.state.config.StateConfig): defaults, keyword overrides through the
constructor and the registry, and one-line errors that name the setting."""

from __future__ import annotations

import math

import pytest
from pydantic import ValidationError

from monorarp.core.camera import CameraModel
from monorarp.core.errors import UserError
from monorarp.pipeline import registry
from monorarp.state.config import StateConfig, StateConfigError, state_config
from monorarp.state.estimator import StateEstimator

CAM = CameraModel.from_fov(640, 360, 60.0, 1.3)


def test_every_setting_has_a_default_and_a_description():
    for name, field in StateConfig.model_fields.items():
        assert not field.is_required(), name
        assert field.description and "\n" not in field.description, name
    assert StateEstimator(CAM).config == StateConfig()


def test_overrides_are_validated_into_the_config_given():
    base = StateConfig(velocity="difference", grade_std=0.01)
    est = StateEstimator(CAM, base, fragment_cover=None)
    assert (est.config.velocity, est.config.grade_std, est.config.fragment_cover) == ("difference", 0.01, None)
    assert base.fragment_cover == 0.9                       # the given config is not changed
    assert StateEstimator(CAM, base).config is base
    assert state_config(None, {"process_std": 3}).process_std == 3.0
    with pytest.raises(ValidationError):
        base.grade_std = 0.02                                # frozen


def test_the_registry_passes_keywords_through():
    est = registry.build("state", "geometric", {"velocity": "difference", "border_tol_px": 6}, CAM)
    assert est.config.velocity == "difference" and est.border_tol_px == 6.0
    assert registry.build("state", "geometric", {}, CAM).border_tol_px == pytest.approx(4.0)


@pytest.mark.parametrize("kw", [{"velocty": "difference"}, {"bogus_kw": 1}])
def test_an_unknown_setting_is_one_line_naming_it(kw):
    with pytest.raises(StateConfigError) as e:
        StateEstimator(CAM, **kw)
    name = next(iter(kw))
    assert isinstance(e.value, UserError) and isinstance(e.value, ValueError)
    assert str(e.value).startswith(f"unknown state setting {name!r}; settings: velocity, motion,")
    assert "\n" not in str(e.value)


@pytest.mark.parametrize("kw", [
    {"velocity": "magic"}, {"motion": "ct"}, {"longitudinal_process_std": 0.0}, {"offset_learn_margin_px": -1.0},
    {"max_inward_offset_m": math.nan}, {"expansion_pixel_std": 0.0}, {"expansion_process_std": math.inf},
    {"expansion_accel_std": 0.0}, {"registration_pixel_std": 0.0}, {"registration_window_s": -1.0},
    {"registration_top": 1.0}, {"registration_interpolation": "nearest"}, {"fusion_sigmas": math.nan},
    {"fusion_pixel_std": -1.0}, {"fragment_cover": 1.5}, {"fragment_width_ratio": math.inf},
    {"fragment_bottom_px": -1.0}, {"reinit_sigmas": 0.0}, {"robust_sigmas": 0.0}, {"bias_tau_s": math.nan},
    {"pixel_std_per_height": -0.1}, {"max_unmeasured_s": -1.0}, {"min_vehicle_width_m": math.nan},
    {"near_border_frac": -0.1}, {"hidden_share": 1.0}, {"side_band_frac": 0.5}, {"contact_offset_std_m": -1.0},
    {"horizon_std_px": math.inf}, {"edge_std_px": -1.0}, {"border_edge_std_px": math.nan}, {"grade_std": -0.01},
    {"border_tol_px": "wide"}, {"max_coast_used": 2.5}, {"process_std": math.nan}])
def test_an_invalid_setting_is_one_line_naming_it(kw):
    name = next(iter(kw))
    with pytest.raises(StateConfigError, match=f"^state setting {name}: .*, got ") as e:
        StateEstimator(CAM, **kw)
    assert "\n" not in str(e.value)


@pytest.mark.parametrize("kw", [{"reinit_sigmas": math.inf}, {"max_unmeasured_s": math.inf},
                                {"robust_sigmas": math.inf}, {"bias_tau_s": math.inf}])
def test_inf_is_accepted_where_it_means_never(kw):
    assert getattr(StateEstimator(CAM, **kw).config, next(iter(kw))) == math.inf


def test_a_config_that_is_not_a_state_config_is_refused():
    with pytest.raises(StateConfigError, match="state config must be a StateConfig or None, got str"):
        StateEstimator(CAM, "difference")
