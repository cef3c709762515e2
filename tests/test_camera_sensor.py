"""The realistic look's camera (harness.render.camera_sensor), against closed forms and cv2."""

from __future__ import annotations

import dataclasses
import math
from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np
import pytest
from scipy.stats import chi2

from harness.render import camera_sensor as cs
from harness.render.look import SensorLook, sample_look

NEUTRAL = SensorLook(exposure_ev=0.0, wb_gains=(1.0, 1.0, 1.0), contrast=1.0, shot_noise=0.0, read_noise=0.0,
                     vignetting=0.0, defocus_px=0.0, jpeg_quality=100)


def _sensor(**kw) -> SensorLook:
    return dataclasses.replace(NEUTRAL, **kw)


def _flat(level: int, h: int = 64, w: int = 96) -> np.ndarray:
    return np.full((h, w, 3), level, np.uint8)


def _lin(v) -> np.ndarray:
    """8-bit code -> linear light, the renderer's 2.2 gamma (independent of the module's LUT)."""
    return (np.asarray(v, dtype=np.float64) / 255.0) ** 2.2


def _scene(h: int = 144, w: int = 256, seed: int = 3) -> np.ndarray:
    """A textured test frame: a sky gradient, a grey road with grain, coloured boxes with hard edges."""
    rng = np.random.default_rng(seed)
    img = np.zeros((h, w, 3), np.uint8)
    y = np.arange(h // 2)[:, None]
    img[: h // 2] = np.stack([230 - y, 200 - y // 2, 160 - y // 2], -1).astype(np.uint8)   # (h/2, 1, 3): BGR rows
    img[h // 2:] = np.clip(80 + rng.normal(0, 12, (h - h // 2, w, 1)), 0, 255).astype(np.uint8)
    for _ in range(12):
        x0, y0 = rng.integers(0, w - 30), rng.integers(h // 3, h - 20)
        img[y0:y0 + rng.integers(8, 20), x0:x0 + rng.integers(10, 30)] = rng.integers(0, 256, 3)
    return img


# ---------------------------------------------------------------- tone curve
@pytest.mark.parametrize("contrast", [0.9, 1.0, 1.3])
def test_tone_curve_closed_form_properties(contrast):
    x = np.linspace(0.0, 2.0, 200001)                          # to 2x the input white (+1 EV)
    f = cs.tone_curve(x, contrast)
    assert f[0] == 0.0
    assert np.all(np.diff(f) > 0)                              # strictly increasing
    assert np.all(f < 1.0) and f[-1] > 0.98                    # rolls off towards 1, never clips
    h = 1e-6                                                    # slope at mid-grey, linear and log-log
    d = (cs.tone_curve(0.18 + h, contrast) - cs.tone_curve(0.18 - h, contrast)) / (2 * h)
    assert d == pytest.approx(contrast, rel=1e-6)
    up, down = cs.tone_curve(0.18 * math.exp(h), contrast), cs.tone_curve(0.18 * math.exp(-h), contrast)
    dlog = (np.log(up) - np.log(down)) / (2 * h)
    assert dlog == pytest.approx(contrast, rel=1e-6)
    assert float(cs.tone_curve(0.18, contrast)) == pytest.approx(0.18, abs=1e-12)


def test_tone_curve_is_c1_at_the_knee_and_identity_below_it():
    xk = cs.KNEE                                               # contrast 1: p = x, knee at x = KNEE
    h = 1e-7
    left = (cs.tone_curve(xk, 1.0) - cs.tone_curve(xk - h, 1.0)) / h
    right = (cs.tone_curve(xk + h, 1.0) - cs.tone_curve(xk, 1.0)) / h
    assert left == pytest.approx(1.0, abs=1e-5) and right == pytest.approx(1.0, abs=1e-5)
    x = np.linspace(0, xk, 1001)
    np.testing.assert_allclose(cs.tone_curve(x, 1.0), x, atol=1e-15)
    assert 0.85 < float(cs.tone_curve(1.0, 1.0)) < 0.95       # input white is rolled off, not clipped


# ---------------------------------------------------------------- neutral chain
def test_neutral_camera_keeps_a_grey_ramp_below_the_knee():
    ramp = np.tile(np.arange(256, dtype=np.uint8)[None, :, None], (32, 1, 3))
    out = cs.apply_camera(ramp, NEUTRAL, seed=0, frame=0)
    assert out.shape == ramp.shape and out.dtype == np.uint8
    mean = out.reshape(-1, 256, 3).mean(axis=(0, 2))
    knee_code = int(255 * cs.KNEE ** (1 / 2.2))                 # 217
    ident = np.arange(3, knee_code)
    assert np.max(np.abs(mean[ident] - ident)) <= 1.0
    # above the knee: the exponential shoulder, written out here from its definition
    x = _lin(np.arange(256))
    k = cs.KNEE
    shoulder = np.where(x <= k, x, 1 - (1 - k) * np.exp(-(x - k) / (1 - k)))
    expected = 255 * shoulder ** (1 / 2.2)
    assert np.max(np.abs(mean[3:] - expected[3:])) <= 1.0
    assert expected[255] == pytest.approx(241.8, abs=0.1)      # input white rolls off to ~242
    assert np.all(np.diff(mean[3:]) >= -0.5)                    # monotone


def test_neutral_camera_keeps_colours():
    img = _scene()
    out = cs.apply_camera(img, dataclasses.replace(NEUTRAL, jpeg_quality=100), 0, 0)
    below = img.max(axis=2) < 210                               # under the shoulder
    diff = np.abs(out.astype(int) - img.astype(int))[below]
    assert np.mean(diff) < 1.5                                  # JPEG at 100 with 4:2:0 chroma aside


# ---------------------------------------------------------------- linear steps
def test_white_balance_and_exposure_scale_the_linear_channels():
    gains, ev = (1.08, 1.0, 0.92), 0.4
    sensor = _sensor(wb_gains=gains, exposure_ev=ev)
    img = _scene()
    s = cs.linear_signal(img, sensor, 0, 0)
    ref = 255 * _lin(img) * (2 ** ev) * np.asarray(gains[::-1])  # BGR order
    np.testing.assert_allclose(s, ref, rtol=1e-5, atol=1e-4)
    # and through the whole chain, in the tone curve's identity region
    out = cs.apply_camera(_flat(100), sensor, 0, 0).astype(float)
    lin = _lin(out.mean(axis=(0, 1)))                          # B, G, R
    np.testing.assert_allclose(lin / _lin(100), np.asarray(gains[::-1]) * 2 ** ev, rtol=0.02)


@pytest.mark.parametrize("sigma", [0.5, 0.8, 1.5])
def test_defocus_is_a_gaussian_of_sigma(sigma):
    img = np.zeros((41, 41, 3), np.uint8)
    img[20, 20] = 255
    s = cs.linear_signal(img, _sensor(defocus_px=sigma), 0, 0)[..., 1].astype(np.float64)
    assert s.sum() == pytest.approx(255.0, rel=1e-4)            # energy kept
    y, x = np.mgrid[:41, :41] - 20
    var_x = (s * x * x).sum() / s.sum()
    var_y = (s * y * y).sum() / s.sum()
    # the Gaussian sampled at whole pixels out to 3 sigma: its variance, in closed form
    k = np.arange(-math.ceil(3 * sigma), math.ceil(3 * sigma) + 1)
    wk = np.exp(-k ** 2 / (2 * sigma ** 2))
    var = (wk * k ** 2).sum() / wk.sum()
    assert var_x == pytest.approx(var, rel=1e-3) and var_y == pytest.approx(var, rel=1e-3)
    if sigma >= 0.8:
        assert var == pytest.approx(sigma ** 2, rel=0.03)      # and that is sigma^2 once sampling resolves it
    assert np.allclose(s, s.T, atol=1e-3)                       # isotropic


def test_defocus_below_threshold_is_skipped():
    img = _scene()
    a = cs.linear_signal(img, _sensor(defocus_px=0.29), 0, 0)
    np.testing.assert_array_equal(a, cs.linear_signal(img, NEUTRAL, 0, 0))
    assert not np.array_equal(cs.linear_signal(img, _sensor(defocus_px=0.3), 0, 0), a)


@pytest.mark.parametrize("v", [0.1, 0.3, 0.4])
def test_vignetting_corner_over_centre(v):
    h, w = 90, 160
    field = cs.vignette_field(h, w, v)
    assert field[0, 0] == pytest.approx(1 - v, rel=1e-5) and field[-1, -1] == pytest.approx(1 - v, rel=1e-5)
    assert field.max() <= 1.0 and field[h // 2, w // 2] == pytest.approx(1.0, abs=1e-4)
    # cos^4 of the field angle of an ideal lens whose corner angle gives the loss v
    tan_c = math.tan(math.acos((1 - v) ** 0.25))
    yy, xx = np.mgrid[:h, :w]
    r = np.hypot(xx - (w - 1) / 2, yy - (h - 1) / 2) / math.hypot((w - 1) / 2, (h - 1) / 2)
    np.testing.assert_allclose(field, np.cos(np.arctan(r * tan_c)) ** 4, rtol=1e-5)
    s = cs.linear_signal(_flat(200, h, w), _sensor(vignetting=v), 0, 0)
    assert s[0, 0, 1] / s[h // 2, w // 2, 1] == pytest.approx(1 - v, rel=1e-3)
    out = _lin(cs.apply_camera(_flat(200, h, w), _sensor(vignetting=v), 0, 0).astype(float))
    corners = np.mean([out[0, 0], out[0, -1], out[-1, 0], out[-1, -1]])
    centre = out[h // 2 - 1:h // 2 + 1, w // 2 - 1:w // 2 + 1].mean()
    assert corners / centre == pytest.approx(1 - v, rel=0.01)


# ---------------------------------------------------------------- noise
@pytest.mark.parametrize("shot,read", [(0.5, 2.0), (0.1, 0.5), (0.0, 1.5), (0.6, 0.0)])
def test_noise_variance_is_poisson_gaussian(shot, read):
    sensor = _sensor(shot_noise=shot, read_noise=read)
    variances = []
    for level in (40, 120, 200):
        img = _flat(level, 128, 256)
        s = cs.linear_signal(img, sensor, 5, level).astype(np.float64)
        signal = 255 * _lin(level)
        n = s.size
        expected = shot * signal + read ** 2
        sample_var = s.var(ddof=1)
        lo, hi = chi2.ppf([1e-6, 1 - 1e-6], n - 1) / (n - 1)
        assert lo * expected <= sample_var <= hi * expected, (level, sample_var, expected)
        assert abs(s.mean() - signal) < 6 * math.sqrt(expected / n)   # unbiased
        variances.append(sample_var)
    if shot > 0:
        assert variances[0] < variances[1] < variances[2]       # grows with the signal


def test_noise_is_gaussian_and_independent_across_pixels_and_channels():
    s = cs.linear_signal(_flat(150, 128, 256), _sensor(shot_noise=0.3, read_noise=1.0), 1, 2).astype(np.float64)
    z = (s - s.mean()) / s.std()
    kurt = np.mean(z ** 4)
    assert kurt == pytest.approx(3.0, abs=0.05)                 # Gaussian (n = 98304: sd of kurtosis 0.016)
    n = z[:, :-1].size
    for a, b in [(z[:, :-1], z[:, 1:]), (z[:-1], z[1:]), (z[..., 0], z[..., 1]), (z[..., 1], z[..., 2])]:
        assert abs(np.mean(a * b)) < 5 / math.sqrt(n)          # uncorrelated neighbours and channels


def test_noise_in_the_output_matches_the_delta_method():
    """Output luma noise = d(code)/dS x the linear noise (the codec's 4:2:0 only averages chroma noise)."""
    shot, read, level = 0.3, 1.5, 120
    out = cs.apply_camera(_flat(level, 128, 256), _sensor(shot_noise=shot, read_noise=read), 3, 4)
    luma = cv2.cvtColor(out, cv2.COLOR_BGR2YCrCb)[..., 0].astype(float)
    signal = 255 * _lin(level)                                  # identity tone region, then 1/2.2 encoding
    slope = (signal / 255) ** (1 / 2.2 - 1) / 2.2               # d code / d S
    per_channel = slope * math.sqrt(shot * signal + read ** 2)
    luma_std = per_channel * math.sqrt(0.299 ** 2 + 0.587 ** 2 + 0.114 ** 2)
    assert luma.std() == pytest.approx(luma_std, rel=0.08)
    assert out.astype(float).mean() == pytest.approx(level, abs=0.6)
    assert out.astype(float).std() < per_channel               # chroma noise smeared by 4:2:0


# ---------------------------------------------------------------- determinism
def test_deterministic_by_seed_and_frame():
    img, sensor = _scene(), sample_look(11).sensor
    a = cs.apply_camera(img, sensor, 7, 3)
    cs.apply_camera(_scene(64, 64), sensor, 7, 3)               # another size in between (new workspace)
    np.testing.assert_array_equal(a, cs.apply_camera(img, sensor, 7, 3))
    assert not np.array_equal(a, cs.apply_camera(img, sensor, 7, 4))
    assert not np.array_equal(a, cs.apply_camera(img, sensor, 8, 3))
    assert np.mean(np.abs(a.astype(int) - img.astype(int))) > 1.0


def test_threads_do_not_share_buffers():
    big, small = _scene(), _scene(72, 128, seed=4)
    sensors = [sample_look(s).sensor for s in range(6)]
    jobs = [(big if i % 2 else small, sensors[i], i) for i in range(6)] * 2
    serial = [cs.apply_camera(img, s, 1, f) for img, s, f in jobs]
    with ThreadPoolExecutor(3) as pool:
        parallel = list(pool.map(lambda j: cs.apply_camera(j[0], j[1], 1, j[2]), jobs))
    for a, b in zip(serial, parallel):
        np.testing.assert_array_equal(a, b)


def test_input_is_not_modified_and_bad_input_is_refused():
    img = _scene()
    keep = img.copy()
    cs.apply_camera(img, sample_look(2).sensor, 0, 0)
    np.testing.assert_array_equal(img, keep)
    with pytest.raises(ValueError):
        cs.apply_camera(img.astype(np.float32), NEUTRAL, 0, 0)
    with pytest.raises(ValueError):
        cs.apply_camera(img, _sensor(read_noise=-1.0), 0, 0)


# ---------------------------------------------------------------- codec
def _sampling_factors(jpeg: bytes) -> list[int]:
    """Per-component (H << 4 | V) sampling bytes of the JPEG's baseline frame header (SOF0)."""
    i = jpeg.index(b"\xff\xc0")
    n = jpeg[i + 9]
    return [jpeg[i + 10 + 3 * k + 1] for k in range(n)]


def test_jpeg_is_4_2_0():
    assert _sampling_factors(cs.encode_jpeg(_scene(), 80)) == [0x22, 0x11, 0x11]


def test_jpeg_psnr_falls_with_quality():
    img = _scene()
    psnr = [cv2.PSNR(img, cs.jpeg_roundtrip(img, q)) for q in (98, 90, 75, 50, 25, 10)]
    assert all(a > b for a, b in zip(psnr, psnr[1:])), psnr
    assert psnr[0] > 35 and psnr[-1] < 32


def test_jpeg_loses_chroma_detail_more_than_luma():
    """4:2:0: a one-pixel chroma checker at constant luma is smeared, a luma checker much less."""
    h, w = 64, 64
    chk = ((np.indices((h, w)).sum(0) % 2) * 2 - 1).astype(np.float32)
    ycrcb = np.zeros((h, w, 3), np.float32)
    ycrcb[..., 0], ycrcb[..., 1], ycrcb[..., 2] = 128, 128 + 40 * chk, 128
    chroma = cv2.cvtColor(ycrcb.astype(np.uint8), cv2.COLOR_YCrCb2BGR)
    ycrcb[..., 0], ycrcb[..., 1] = 128 + 40 * chk, 128
    luma = cv2.cvtColor(ycrcb.astype(np.uint8), cv2.COLOR_YCrCb2BGR)
    kept = []
    for img, ch in ((chroma, 1), (luma, 0)):
        a = cv2.cvtColor(img, cv2.COLOR_BGR2YCrCb)[..., ch].astype(float)
        b = cv2.cvtColor(cs.jpeg_roundtrip(img, 95), cv2.COLOR_BGR2YCrCb)[..., ch].astype(float)
        kept.append(np.std(b) / np.std(a))
    assert kept[0] < 0.2 and kept[1] > 0.8


# ---------------------------------------------------------------- H.264 on a clip
def _clip(n: int = 12, h: int = 64, w: int = 96) -> list[np.ndarray]:
    base = cv2.resize(_scene(), (w + 2 * n, h), interpolation=cv2.INTER_AREA)
    return [np.ascontiguousarray(base[:, i:i + w]) for i in range(n)]     # a slow pan


def test_h264_roundtrip_is_deterministic_and_lossy_by_crf():
    clip = _clip()
    a = cs.encode_h264_roundtrip(clip, crf=20)
    assert len(a) == len(clip) and all(f.shape == clip[0].shape and f.dtype == np.uint8 for f in a)
    b = cs.encode_h264_roundtrip(clip, crf=20)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    worse = cs.encode_h264_roundtrip(clip, crf=40)
    p20 = np.mean([cv2.PSNR(x, y) for x, y in zip(clip, a)])
    p40 = np.mean([cv2.PSNR(x, y) for x, y in zip(clip, worse)])
    assert p20 > 30 and p40 < p20 - 3, (p20, p40)
    with pytest.raises(ValueError):
        cs.encode_h264_roundtrip([np.zeros((63, 96, 3), np.uint8)], crf=20)
