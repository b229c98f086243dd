"""upsr.research.synth.recording: a RealSense recording written by the SDK, read back by upsr."""

import ctypes.util
import importlib.util

import numpy as np
import pytest

from upsr.errors import InputError

pytestmark = pytest.mark.skipif(
    importlib.util.find_spec("pyrealsense2") is None or ctypes.util.find_library("usb-1.0") is None,
    reason="the RealSense SDK (pyrealsense2 and libusb) is not installed",
)


@pytest.mark.parametrize("units_m", [0.001, 0.0001])
def test_recording_reads_back(tmp_path, units_m):
    from upsr.io import read_intrinsics, read_video
    from upsr.research.synth.recording import write_realsense_recording

    rng = np.random.default_rng(0)
    frames = rng.uniform(400.0, 3000.0, (3, 12, 16))
    frames[:, 0, 0] = 0.0
    frames[1, 2, 3] = np.nan
    path = write_realsense_recording(
        tmp_path / "r.db3", frames, units_m=units_m, intrinsics=(20.0, 21.0, 7.5, 5.5)
    )
    got = read_video(path)
    want = np.round(np.nan_to_num(frames) / (units_m * 1000.0)) * (units_m * 1000.0)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-3)
    assert got[1, 2, 3] == 0 and (got[:, 0, 0] == 0).all()
    cam = read_intrinsics(path)
    assert (cam.fx, cam.fy, cam.cx, cam.cy, cam.width, cam.height) == (20, 21, 7.5, 5.5, 16, 12)


def test_recording_refuses_what_16_bits_cannot_hold(tmp_path):
    from upsr.research.synth.recording import write_realsense_recording

    with pytest.raises(InputError, match="16-bit"):
        write_realsense_recording(tmp_path / "r.db3", np.full((1, 4, 4), 7000.0), units_m=1e-4)
    with pytest.raises(InputError, match="T, h, w"):
        write_realsense_recording(tmp_path / "r.db3", np.ones((4, 4)))
    assert not (tmp_path / "r.db3").exists()
