"""monorarp.app.video.writer: H.264 mp4 writing, read back with OpenCV's own decoder."""

from __future__ import annotations

import hashlib

import cv2
import numpy as np
import pytest

from monorarp.app.video.writer import VideoWriter, read_video


def _frames(w: int, h: int, n: int) -> list[np.ndarray]:
    """Smooth, coloured test frames (distinct B, G, R content) with a moving square."""
    yy, xx = np.mgrid[0:h, 0:w]
    out = []
    for i in range(n):
        img = np.zeros((h, w, 3), np.uint8)
        img[..., 0] = 200  # blue background
        img[..., 1] = (xx * 255 // max(w - 1, 1)).astype(np.uint8)
        img[..., 2] = 40
        x0 = 10 + 4 * i
        img[20:50, x0:x0 + 30] = (0, 0, 255)  # red square, BGR
        out.append(img)
    return out


@pytest.mark.parametrize("size", [(160, 96), (161, 97)])
def test_round_trip_count_timestamps_colours(tmp_path, size):
    w, h = size
    frames = _frames(w, h, 12)
    path = tmp_path / "v.mp4"
    with VideoWriter(path, 15.0, (w, h)) as vw:
        assert vw.backend == "ffmpeg-libx264"
        for f in frames:
            vw.write(f)
    cap = cv2.VideoCapture(str(path))
    assert int(cap.get(cv2.CAP_PROP_FOURCC)).to_bytes(4, "little") in (b"avc1", b"h264", b"H264")
    cap.release()
    got = list(read_video(path, size=(w, h)))
    assert len(got) == len(frames)
    np.testing.assert_allclose([g.t for g in got], np.arange(12) / 15.0, atol=1e-3)
    for g, f in zip(got, frames):
        assert g.image.shape == (h, w, 3)
        err = np.abs(g.image.astype(int) - f.astype(int))
        assert err.mean() < 3.0  # lossy but faithful; a swapped R/B would give ~100
    # the red square stays red (BGR order kept)
    b, g_, r = got[0].image[35, 25]
    assert r > 200 and b < 60


def test_identical_frames_give_identical_bytes(tmp_path):
    frames = _frames(128, 72, 8)
    digests = []
    for name in ("a.mp4", "b.mp4"):
        with VideoWriter(tmp_path / name, 15.0, (128, 72)) as vw:
            for f in frames:
                vw.write(f)
        digests.append(hashlib.sha256((tmp_path / name).read_bytes()).hexdigest())
    assert digests[0] == digests[1]


def test_rejects_wrong_frame(tmp_path):
    with VideoWriter(tmp_path / "v.mp4", 10, (64, 48)) as vw:
        with pytest.raises(ValueError, match="uint8"):
            vw.write(np.zeros((48, 64, 3), np.float32))
        with pytest.raises(ValueError):
            vw.write(np.zeros((64, 48, 3), np.uint8))
        vw.write(np.zeros((48, 64, 3), np.uint8))
