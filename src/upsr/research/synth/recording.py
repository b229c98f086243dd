"""RealSense recordings written by the RealSense SDK itself, without a camera.

A ``pyrealsense2.software_device`` with one Z16 depth stream is recorded by
``pyrealsense2.recorder`` while depth frames are fed to it: the file is what a camera's
recording is (the SDK's own format, ``.db3`` in SDK 2.56+), for ``upsr run``, ``upsr batch``
and ``upsr live`` (which plays it back through the SDK as a camera). Needs the optional extra
``upsr[realsense]`` and the system's libusb.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import numpy.typing as npt

from upsr.errors import InputError

__all__ = ["write_realsense_recording"]


def write_realsense_recording(
    path: str | Path,
    frames_mm: npt.ArrayLike,
    *,
    fps: int = 30,
    units_m: float = 0.001,
    intrinsics: tuple[float, float, float, float] | None = None,
    real_time: bool = False,
    frame_numbers: Sequence[int] | None = None,
) -> Path:
    """Record ``frames_mm`` as a RealSense depth stream through the SDK.

    Parameters
    ----------
    path : path
        The recording to write (``.db3`` for SDK 2.56+).
    frames_mm : array_like (T, h, w)
        Depth in mm (0 or NaN: no depth); stored as 16-bit raw units of ``units_m``.
    fps : int
        The stream's frame rate.
    units_m : float
        The Depth Units option (metres per raw unit: 0.001, or 0.0001 as a D405's).
    intrinsics : (fx, fy, cx, cy), optional
        Of the depth stream (px); default fx = fy = 0.8·w at the image centre.
    real_time : bool
        Feed one frame every 1/``fps`` s, so that the recording plays back at the camera's
        rate (the SDK records the time of arrival); else as fast as possible (the whole
        recording then plays back within a few milliseconds).
    frame_numbers : sequence of int, optional
        The camera's number of each frame (default 1, 2, …; gaps: frames the camera dropped
        while recording).

    Returns
    -------
    Path
    """
    import pyrealsense2 as rs

    z = np.nan_to_num(np.asarray(frames_mm, np.float64), nan=0.0)
    if z.ndim != 3 or z.shape[0] < 1:
        raise InputError(f"frames_mm must be (T, h, w), got shape {z.shape}")
    raw = np.round(z / (units_m * 1000.0))
    if raw.min() < 0 or raw.max() > 65535:
        raise InputError("frames_mm out of the 16-bit range of these depth units")
    raw = raw.astype(np.uint16)
    n, h, w = raw.shape
    fx, fy, cx, cy = intrinsics or (0.8 * w, 0.8 * w, w / 2 - 0.5, h / 2 - 0.5)
    dev = rs.software_device()
    sensor = dev.add_sensor("Depth")
    intr = rs.intrinsics()
    intr.width, intr.height = w, h
    intr.fx, intr.fy, intr.ppx, intr.ppy = fx, fy, cx, cy
    intr.model = rs.distortion.none
    intr.coeffs = [0.0] * 5
    vs = rs.video_stream()
    vs.type = rs.stream.depth
    vs.uid, vs.index = 0, 0
    vs.width, vs.height, vs.fps, vs.bpp = w, h, fps, 2
    vs.fmt = rs.format.z16
    vs.intrinsics = intr
    profile = sensor.add_video_stream(vs)
    sensor.add_read_only_option(rs.option.depth_units, units_m)
    recorder = rs.recorder(str(path), dev)
    sensor.open(profile)
    queue = rs.frame_queue(n + 2)
    sensor.start(queue)
    start = time.perf_counter()
    for t in range(n):
        if real_time:
            time.sleep(max(0.0, start + t / fps - time.perf_counter()))
        f = rs.software_video_frame()
        f.pixels = np.ascontiguousarray(raw[t])
        f.bpp = 2
        f.stride = w * 2
        f.timestamp = t * 1000.0 / fps
        f.domain = rs.timestamp_domain.hardware_clock
        f.frame_number = t + 1 if frame_numbers is None else int(frame_numbers[t])
        f.profile = profile.as_video_stream_profile()
        sensor.on_video_frame(f)
        queue.wait_for_frame(1000)
    sensor.stop()
    sensor.close()
    del recorder  # closes the file
    return Path(path)
