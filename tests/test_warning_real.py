"""The warning stage's settings where frames are real (monorarp.app.options.REAL_FRAMES_WARNING, docs/warning_real.md).

The states below are synthetic, with the numbers of real tracks measured in docs/warning_real.md: a closing
lead whose range filter has just restarted and over-reads its closing speed while its registered patch reads
the true rate (the stress clips), and the real clip's two nearest false threats (a next-lane car read drifting
in and closing at 60 m, a lane-dash box read closing in path at 30 m).
"""

import argparse

import pytest

from monorarp.app.options import REAL_FRAMES, REAL_FRAMES_WARNING, add_pipeline_options, default_pipeline_config, \
    pipeline_config
from monorarp.core.types import ObjectState
from monorarp.pipeline.config import ComponentConfig, PipelineConfig
from monorarp.warning.config import WarningConfig
from monorarp.warning.fcw import ForwardCollisionWarning

EGO_FRONT_M = 4.5 / 2      # the ego's front ahead of the camera (ego length 4.5 m, camera offset 0)


def real_stage() -> ForwardCollisionWarning:
    """The warning stage a real-frame command (``monorarp video``) builds."""
    cfg = default_pipeline_config(REAL_FRAMES).warning
    assert cfg is not None and cfg.name == "fcw"
    return ForwardCollisionWarning(**cfg.kwargs)


def restarted_lead() -> ObjectState:
    # 14.8 m ahead in the ego's lane, truly closing at 5 m/s (patch rate 5 / 17.8 ~ 0.28 /s); its filter,
    # 0.1 s after a restart, reads 11.5 +- 2 m/s of closing speed; the box width grows at 0.8 +- 0.13 /s
    return ObjectState(3, 0.0, 14.8, 0.0, -11.5, v_x_std=0.4, v_y_std=2.0, age_s=0.12,
                       expansion_rate=0.8, expansion_rate_std=0.13, registered_rate=0.27, registered_rate_std=0.04)


def test_real_frames_drop_the_registered_veto_and_nothing_else():
    assert REAL_FRAMES_WARNING == {"registered_share": None}
    assert default_pipeline_config(REAL_FRAMES).warning == ComponentConfig(name="fcw", kwargs=REAL_FRAMES_WARNING)
    # the simulation commands keep every default
    assert default_pipeline_config().warning == PipelineConfig().warning == ComponentConfig(name="fcw")
    assert WarningConfig().registered_share == 0.6
    real = real_stage().config
    assert real.model_dump() == WarningConfig(registered_share=None).model_dump()


def test_a_restarted_lead_warns_on_real_frames_and_not_with_the_simulated_defaults():
    lead = {3: restarted_lead()}
    # simulated defaults: the patch (0.27 + 0.04 /s) is under 0.6 x 11.5 / 14.8 = 0.47 /s: vetoed
    assert ForwardCollisionWarning().threats(lead) == {}
    # real frames: the threat at the closed-form TTC (closing speed less 0.5 of its sigma)
    ttc = real_stage().threats(lead)[3]
    assert ttc == pytest.approx((14.8 - EGO_FRONT_M) / (11.5 - 0.5 * 2.0))
    # and the alert comes: the patch does not confirm the over-read speed, so after min_on_s (0.1 s)
    w = real_stage()
    out = [w.update(lead, None, k / 25.0) for k in range(5)]
    assert [o.active for o in out] == [False, False, False, True, True] and out[3].track_id == 3


def test_the_real_clips_nearest_false_threats_stay_vetoed():
    # track 1, frame 81: next lane (6.7 m left), 61 m, read drifting in at 4.4 m/s and closing at 14 m/s
    # (-20 m/s^2), its box and patch shrinking (it pulls away): the far looming share vetoes it
    drifting = ObjectState(1, -6.692, 61.104, 4.351, -14.056, v_x_std=0.474, v_y_std=2.289, a_y=-20.211,
                           a_y_std=3.399, age_s=1.28, expansion_rate=-0.078, expansion_rate_std=0.027,
                           registered_rate=-0.203, registered_rate_std=0.176)
    w = real_stage()
    assert w.threats({1: drifting}, ego_speed=27.4) == {}
    assert ForwardCollisionWarning().threats({1: drifting}, ego_speed=27.4) == {}
    loose = ForwardCollisionWarning(registered_share=None, looming_sigmas=None)
    assert 0 < loose.threats({1: drifting}, ego_speed=27.4)[1] < 3.0          # what the looming rule stops
    # track 16, frame 194: a lane dash's box, in path at 29.6 m, read closing at 20.5 m/s, 0.24 s old
    dash = ObjectState(16, -0.868, 29.585, 0.627, -20.521, v_x_std=2.0, v_y_std=3.635, a_y=-0.981, a_y_std=5.013,
                       age_s=0.24, expansion_rate=0.567, expansion_rate_std=0.761)
    assert w.threats({16: dash}, ego_speed=27.2) == {}
    older = ObjectState(**{**dash.__dict__, "age_s": 0.32})    # past young_far_age_s: only the gate held it
    assert w.threats({16: older}, ego_speed=27.2)[16] < 3.0


def test_a_configs_own_warning_settings_win_over_the_real_frame_ones():
    p = argparse.ArgumentParser()
    add_pipeline_options(p, defaults=REAL_FRAMES)
    args = p.parse_args([])
    base = PipelineConfig(warning=ComponentConfig(name="fcw", kwargs={"registered_share": 0.5, "hold_s": 0.5}))
    assert pipeline_config(args, base).warning.kwargs == {"registered_share": 0.5, "hold_s": 0.5}
    assert pipeline_config(args, PipelineConfig(warning=None)).warning is None
    # a simulation command's parser adds nothing
    p = argparse.ArgumentParser()
    add_pipeline_options(p)
    assert pipeline_config(p.parse_args([]), base).warning == base.warning
