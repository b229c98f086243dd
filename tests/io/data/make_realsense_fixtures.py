"""Regenerate the RealSense recordings of tests/io/data/realsense with the real SDK.

No camera is needed: a ``pyrealsense2.software_device`` with one Z16 depth stream is recorded
by ``pyrealsense2.recorder``. The format follows the SDK installed:

- librealsense < 2.57 writes ROS 1 ``.bag`` files (``rs256_*.bag``),
- librealsense 2.57+ writes ROS 2 sqlite ``.db3`` files without ``metadata.yaml``
  (``rs259_*.db3``, compressedDepth PNG).

Each recording is played back by the same SDK and what it reports (depth × its depth units in
mm, frame timestamps in ms, intrinsics) is saved beside it as ``NAME.sdk.npz``: the tests
compare upsr's reading to that (and to a live playback when pyrealsense2 is installed)::

    pip install --target /tmp/rs256 pyrealsense2==2.56.5.9235
    PYTHONPATH=/tmp/rs256 python tests/io/data/make_realsense_fixtures.py   # the .bag files
    pip install 'upsr[realsense]'   # pyrealsense2 2.59+
    python tests/io/data/make_realsense_fixtures.py                         # the .db3 files
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import pyrealsense2 as rs

HERE = Path(__file__).resolve().parent / "realsense"
W, H, N = 64, 48, 3
FX, FY, PPX, PPY = 50.5, 51.25, 31.7, 23.2
T0_MS, DT_MS = 1000.0, 33.3


def sdk_version() -> tuple[int, int]:
    """(major, minor) of the pyrealsense2 imported."""
    v = getattr(rs, "__version__", "") or ""
    if not v:  # 2.56 wheels have no __version__: their dist-info says it
        from importlib.metadata import version

        v = version("pyrealsense2")
    major, minor = v.split(".")[:2]
    return int(major), int(minor)


def depth_raw(i: int, units_m: float) -> np.ndarray:
    """Frame i, raw Z16: a tilted plane from 0.5 m to ~3.4 m with holes and a step."""
    y, x = np.mgrid[0:H, 0:W]
    mm = 500.0 + 40.0 * x + 12.0 * y + 3.0 * i
    mm[10:20, 30:40] += 250.0
    raw = np.round(mm / (units_m * 1000.0)).astype(np.uint16)
    raw[(x + 2 * y + i) % 17 == 0] = 0
    return raw


def record(path: Path, units_m: float) -> None:
    dev = rs.software_device()
    sensor = dev.add_sensor("Depth")
    intr = rs.intrinsics()
    intr.width, intr.height, intr.fx, intr.fy, intr.ppx, intr.ppy = W, H, FX, FY, PPX, PPY
    intr.model, intr.coeffs = rs.distortion.none, [0.0] * 5
    vs = rs.video_stream()
    vs.type, vs.index, vs.uid, vs.width, vs.height = rs.stream.depth, 0, 0, W, H
    vs.fps, vs.bpp, vs.fmt, vs.intrinsics = 30, 2, rs.format.z16, intr
    profile = sensor.add_video_stream(vs)
    sensor.add_read_only_option(rs.option.depth_units, units_m)
    recorder = rs.recorder(str(path), dev)
    queue = rs.frame_queue()
    sensor.open(profile)
    sensor.start(queue)
    for i in range(N):
        f = rs.software_video_frame()
        f.pixels = depth_raw(i, units_m)
        f.stride, f.bpp = 2 * W, 2
        f.timestamp, f.domain, f.frame_number = (
            T0_MS + DT_MS * i,
            rs.timestamp_domain.system_time,
            i,
        )
        f.profile = profile.as_video_stream_profile()
        f.depth_units = units_m
        sensor.on_video_frame(f)
        time.sleep(0.05)
    sensor.stop()
    sensor.close()
    del recorder


def playback(path: Path) -> dict[str, np.ndarray]:
    """What the SDK reads back: depth (mm), timestamps (ms), intrinsics."""
    pipe, cfg = rs.pipeline(), rs.config()
    cfg.enable_device_from_file(str(path), repeat_playback=False)
    prof = pipe.start(cfg)
    prof.get_device().as_playback().set_real_time(False)
    depth, stamps = [], []
    while True:
        ok, fs = pipe.try_wait_for_frames(2000)
        if not ok:
            break
        d = fs.get_depth_frame()
        depth.append(np.asanyarray(d.get_data()).astype(np.float64) * d.get_units() * 1000.0)
        stamps.append(d.get_timestamp())
    i = prof.get_stream(rs.stream.depth).as_video_stream_profile().get_intrinsics()
    pipe.stop()
    return {
        "depth_mm": np.asarray(depth),
        "timestamps_ms": np.asarray(stamps),
        "intrinsics": np.asarray([i.fx, i.fy, i.ppx, i.ppy, i.width, i.height], np.float64),
    }


def main() -> int:
    HERE.mkdir(exist_ok=True)
    major, minor = sdk_version()
    ros1 = (major, minor) < (2, 57)
    prefix, suffix = ("rs256", ".bag") if ros1 else ("rs259", ".db3")
    for label, units in (("1mm", 0.001), ("100um", 0.0001)):
        path = HERE / f"{prefix}_{label}{suffix}"
        path.unlink(missing_ok=True)
        record(path, units)
        np.savez_compressed(path.with_name(path.name + ".sdk.npz"), **playback(path))
        print(f"{path} ({path.stat().st_size} bytes, librealsense {major}.{minor})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
