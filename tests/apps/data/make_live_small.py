"""Write ``live_small.db3``: a small depth recording made by the RealSense SDK itself.

No camera: a ``pyrealsense2.software_device`` with one 48×40 Z16 depth stream (1 mm units,
30 frames/s) is recorded by ``pyrealsense2.recorder`` while 12 synthetic frames are fed to it
(a slanted wall, a box moving 2 px per frame, Laplacian noise of 8 mm, a few pixels without
depth). ``upsr live`` plays it back through the SDK as a camera (tests/apps/cli/test_live.py).

    python tests/apps/data/make_live_small.py [OUT.db3]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

W, H, FPS, N = 48, 40, 30, 12


def frames(seed: int = 0) -> np.ndarray:
    """The 12 uint16 (mm) frames of the recording."""
    rng = np.random.default_rng(seed)
    ys, xs = np.mgrid[0:H, 0:W].astype(np.float32)
    out = np.empty((N, H, W), np.uint16)
    for t in range(N):
        z = 2000 + 6 * xs + 2 * ys
        z[12:26, 6 + 2 * t : 16 + 2 * t] = 1300.0
        z += rng.laplace(0, 8 / np.sqrt(2), z.shape).astype(np.float32)
        z[rng.random(z.shape) < 0.01] = 0
        out[t] = np.round(z).astype(np.uint16)
    return out


def write(path: Path) -> Path:
    import pyrealsense2 as rs

    dev = rs.software_device()
    sensor = dev.add_sensor("Depth")
    intr = rs.intrinsics()
    intr.width, intr.height = W, H
    intr.fx = intr.fy = 40.0
    intr.ppx, intr.ppy = W / 2 - 0.5, H / 2 - 0.5
    intr.model = rs.distortion.none
    intr.coeffs = [0.0] * 5
    vs = rs.video_stream()
    vs.type = rs.stream.depth
    vs.uid, vs.index = 0, 0
    vs.width, vs.height, vs.fps, vs.bpp = W, H, FPS, 2
    vs.fmt = rs.format.z16
    vs.intrinsics = intr
    profile = sensor.add_video_stream(vs)
    sensor.add_read_only_option(rs.option.depth_units, 0.001)
    recorder = rs.recorder(str(path), dev)
    sensor.open(profile)
    queue = rs.frame_queue(N + 2)
    sensor.start(queue)
    for t, z in enumerate(frames()):
        f = rs.software_video_frame()
        f.pixels = np.ascontiguousarray(z)
        f.bpp = 2
        f.stride = W * 2
        f.timestamp = t * 1000.0 / FPS
        f.domain = rs.timestamp_domain.hardware_clock
        f.frame_number = t + 1
        f.profile = profile.as_video_stream_profile()
        sensor.on_video_frame(f)
        queue.wait_for_frame(1000)
    sensor.stop()
    sensor.close()
    del recorder  # closes the file
    return path


if __name__ == "__main__":
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).with_name("live_small.db3")
    print(write(out), out.stat().st_size, "bytes")
