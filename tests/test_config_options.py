"""The shared pipeline options (monorarp/app/options.py): every command's options give the
PipelineConfig it built before, defaults are the config's, bad names are one line and exit 2."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from monorarp.pipeline import registry
from monorarp.app.cli import build_parser, main
from monorarp.warning.thresholds import TTC_CUE_THRESHOLD_S
from monorarp.state.config import REAL_FRAMES_STATE
from monorarp.app.options import (CLI_EGO_SPEED, REAL_FRAMES, REAL_FRAMES_RISK, REAL_FRAMES_WARNING,
                                  add_pipeline_options, default_pipeline_config, pipeline_config)
from monorarp.core.errors import UserError
from monorarp.pipeline.config import REAL_WORLD_DETECTOR, ComponentConfig, PipelineConfig
from monorarp.app.video.run import VideoRunOptions
from monorarp.pipeline.runner import Pipeline

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "monorarp" / "models" / "centernet_vehicle.onnx"


def C(name: str, **kw) -> ComponentConfig:
    return ComponentConfig(name=name, kwargs=kw)


def parse(*argv: str) -> argparse.Namespace:
    return build_parser().parse_args(list(argv))


def run_config(*argv: str) -> PipelineConfig:
    from harness.commands.detector_args import pipeline_config as harness_config

    return harness_config(parse("run", "s.yaml", *argv))


# -------------------------------------------------------------------- round trips
def test_run_defaults_are_what_run_built_before():
    assert run_config() == PipelineConfig(detector=C("centernet"), tracker=C("particle"),
                                          state=C("geometric", velocity="kalman"), risk=C("ttc"),
                                          ego_speed=C("ground_track"), horizon=None)


def test_run_options_round_trip():
    cfg = run_config("--detector", "oracle", "--oracle-jitter", "1", "--tracker", "sort", "--risk", "monte_carlo",
                     "--velocity", "difference", "--ego-speed", "lsd_period", "--horizon", "online")
    assert cfg == PipelineConfig(detector=C("oracle", jitter_px=1.0), tracker=C("sort"),
                                 state=C("geometric", velocity="difference"), risk=C("monte_carlo"),
                                 ego_speed=C("lsd_period"), horizon=C("online"))
    assert run_config("--ego-speed", "none", "--refine-bottom", "off").ego_speed is None
    assert run_config("--refine-bottom", "off").detector == C("centernet", refine_bottom=False)
    assert run_config("--weak-detections", "0.3").detector == C("centernet", weak_score_threshold=0.3)


def test_video_options_round_trip():
    cfg = pipeline_config(parse("video", "in.mp4", "--camera", "c.yaml", "--tracker", "kcf", "--risk",
                                "monte_carlo", "--horizon", "online", "--ego-speed", "None"))
    # as the video command built it before, plus the state estimator's velocity written out (its default)
    # and the real-frame state settings (the size prior)
    assert cfg == PipelineConfig(detector=C("yolox"), tracker=C("kcf"),
                                 state=C("geometric", **REAL_FRAMES_STATE, velocity="kalman"),
                                 risk=C("monte_carlo"), ego_speed=None, horizon=C("online"),
                                 warning=C("fcw", **REAL_FRAMES_WARNING))


def test_defaults_identical_across_commands():
    from harness.commands.detector_args import pipeline_config as harness_config

    run = run_config()
    video = pipeline_config(parse("video", "in.mp4", "--camera", "c.yaml"))
    bench = harness_config(parse("bench", "trackers"))
    card = harness_config(parse("scorecard", "--out", "x"))
    kitti = pipeline_config(parse("eval", "kitti", "d", "--out", "x"))
    assert run == default_pipeline_config()
    assert video == default_pipeline_config(REAL_FRAMES) == VideoRunOptions().pipeline
    # only the detector and the state's, TTC risk's and warning's real-frame settings differ
    assert video == run.model_copy(update={"detector": C(REAL_WORLD_DETECTOR),
                                           "state": C("geometric", **REAL_FRAMES_STATE, velocity="kalman"),
                                           "risk": C("ttc", **REAL_FRAMES_RISK),
                                           "warning": C("fcw", **REAL_FRAMES_WARNING)})
    assert run.ego_speed == C(CLI_EGO_SPEED) and PipelineConfig().ego_speed is None
    for cfg in (run, video, bench, card, kitti):
        assert cfg.detector.name == (REAL_WORLD_DETECTOR if cfg is video else PipelineConfig().detector.name)
        assert cfg.tracker.name == PipelineConfig().tracker.name
        assert cfg.risk == (C("ttc", **REAL_FRAMES_RISK) if cfg is video else PipelineConfig().risk)
        assert cfg.warning == (C("fcw", **REAL_FRAMES_WARNING) if cfg is video else PipelineConfig().warning)
    # real frames: yolox; rendered ones: centernet
    assert REAL_WORLD_DETECTOR == "yolox" and PipelineConfig().detector.name == "centernet"
    assert parse("eval", "kitti", "d", "--out", "x").detector is None    # by the dataset: test_yolox.py
    assert parse("run", "s.yaml").warning_threshold == TTC_CUE_THRESHOLD_S


def test_real_frames_risk_settings_go_to_ttc_estimators_only():
    assert REAL_FRAMES_RISK == {"velocity_sigmas": 2.0}
    video = lambda *a: pipeline_config(parse("video", "in.mp4", "--camera", "c.yaml", *a)).risk   # noqa: E731
    assert video("--risk", "manoeuvre_ttc") == C("manoeuvre_ttc", **REAL_FRAMES_RISK)   # a TTCRiskEstimator
    assert video("--risk", "monte_carlo") == C("monte_carlo")                          # it takes no such setting
    assert run_config("--risk", "ttc").risk == C("ttc")                                # rendered frames: off


def test_onnx_path_is_the_detector_name_and_builds(tmp_path):
    cfg = pipeline_config(parse("video", "in.mp4", "--camera", "c.yaml", "--detector", str(MODEL),
                                "--refine-bottom", "on"))
    assert cfg.detector == C(str(MODEL), refine_bottom=True)
    from monorarp.core.camera import CameraModel
    from monorarp.detection.centernet import CenterNetDetector

    pipe = Pipeline.from_config(cfg, CameraModel.from_fov(640, 360, 70.0, height_m=1.3))
    assert isinstance(pipe.detector, CenterNetDetector)


# ------------------------------------------------------------------------- refusals
@pytest.mark.parametrize("argv, option", [
    (["run", "missing.yaml", "--risk", "nope"], "--risk"),
    (["run", "missing.yaml", "--ego-speed", "nope"], "--ego-speed"),
    (["run", "missing.yaml", "--horizon", "nope"], "--horizon"),
    (["run", "missing.yaml", "--detector", "nope"], "--detector"),
    (["scorecard", "--out", "x", "--tracker", "nope"], "--tracker"),
])
def test_unknown_name_is_one_line_exit_2(argv, option, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert f"{option}: unknown" in err and "available:" in err


def test_video_leaves_names_to_the_run_after_its_input_checks(tmp_path, capsys):
    args = parse("video", "in.mp4", "--camera", "c.yaml", "--tracker", "nope")
    assert pipeline_config(args, check=False).tracker == C("nope")
    assert main(["video", str(tmp_path / "absent.mp4"), "--camera", "c.yaml", "--tracker", "nope"]) == 2
    assert "nope" not in capsys.readouterr().err     # the missing camera/input is the error reported


def test_options_that_do_not_apply_are_refused():
    with pytest.raises(UserError, match="--refine-bottom"):
        run_config("--detector", "yolo", "--refine-bottom", "on")
    with pytest.raises(UserError, match="--weak-detections applies to the CenterNet detector, not 'oracle'"):
        run_config("--detector", "oracle", "--weak-detections", "0.3")
    with pytest.raises(UserError, match=r"--weak-detections must be a score in \[0, 1\], got 1.5"):
        run_config("--weak-detections", "1.5")
    with pytest.raises(UserError, match="need --detector oracle"):
        run_config("--oracle-jitter", "1")


@pytest.mark.parametrize("name", ["centernet", "centernet_robust", "centernet_dense"])
def test_centernet_options_apply_to_every_registered_centernet_model(name):
    cfg = run_config("--detector", name, "--weak-detections", "0.3", "--refine-bottom", "off")
    assert cfg.detector == C(name, refine_bottom=False, weak_score_threshold=0.3)


def test_validate_names_before_any_model_loads(tmp_path):
    cfg = PipelineConfig(detector=C(str(tmp_path / "absent.onnx")), tracker=C("nope"))
    with pytest.raises(registry.UnknownComponentError, match="unknown tracker 'nope'"):
        Pipeline.from_config(cfg)    # the missing model file is never opened


def test_only_chosen_stages_get_options():
    p = argparse.ArgumentParser()
    add_pipeline_options(p, stages=("tracker",))
    args = p.parse_args([])
    assert not hasattr(args, "detector") and not hasattr(args, "risk")
    assert pipeline_config(args) == PipelineConfig()
    with pytest.raises(ValueError, match="no options for stages"):
        add_pipeline_options(argparse.ArgumentParser(), stages=("warp",))


# --------------------------------------------------------------------- sweep variants
def test_variant_config_and_run_mapping(tmp_path):
    from harness.sweep.spec import Variant, run_mapping

    cfg = Variant(name="v", detector="m.onnx", tracker="kcf", velocity="difference").pipeline_config(tmp_path)
    assert cfg.detector.name == str((tmp_path / "m.onnx").resolve())
    assert cfg.ego_speed is None and cfg.warning == C("fcw") and cfg.state == C("geometric", velocity="difference")
    mapping = run_mapping(cfg)
    assert list(mapping) == ["detector", "tracker", "state", "risk", "ego_speed", "warning"]   # no horizon key
    assert PipelineConfig.model_validate(mapping) == cfg
    assert "horizon" in run_mapping(Variant(name="h", horizon="online").pipeline_config(tmp_path))


@pytest.mark.parametrize("argv", [
    ["run", "missing.yaml", "--weak-detections", "0.2", "--tracker", "sort"],
    ["video", "absent.mp4", "--camera", "c.yaml", "--detector", "centernet", "--weak-detections", "0.2",
     "--tracker", "bytetrack"],
])
def test_weak_detections_need_a_tracker_that_takes_them(argv, capsys):
    """Weak boxes go only to a tracker declaring ``uses_weak_detections``: for another one the option is refused."""
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--weak-detections: weak detections go only to a tracker that takes them" in err
    assert run_config("--weak-detections", "0.2", "--tracker", "particle").tracker == C("particle")


def test_weak_detections_in_a_sweep_variant_need_a_tracker_that_takes_them(tmp_path):
    from harness.sweep.spec import Variant

    cfg = Variant(name="v", detector_kwargs={"weak_score_threshold": 0.2}, tracker="sort").pipeline_config(tmp_path)
    with pytest.raises(UserError, match=r"detector_kwargs.weak_score_threshold: .* tracker 'sort' takes none"):
        cfg.validate_names()
    PipelineConfig(detector=C("centernet", weak_score_threshold=0.2)).validate_names()   # particle takes them
