"""Write ``live_small.db3``: a small depth recording made by the RealSense SDK itself.

No camera: a ``pyrealsense2.software_device`` with one 48×40 Z16 depth stream (1 mm units,
30 frames/s) is recorded by ``pyrealsense2.recorder`` while 12 synthetic frames are fed to it
(a slanted wall, a box moving 2 px per frame, Laplacian noise of 8 mm, a few pixels without
depth; :func:`upsr.research.synth.recording.write_realsense_recording`). ``upsr live`` plays
it back through the SDK as a camera (tests/apps/cli/test_live.py).

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


def write(path: Path, units_m: float = 0.001) -> Path:
    """Record :func:`frames` through the SDK (depth units ``units_m``) at ``path``."""
    from upsr.research.synth.recording import write_realsense_recording

    return write_realsense_recording(
        path, frames(), fps=FPS, units_m=units_m, intrinsics=(40.0, 40.0, W / 2 - 0.5, H / 2 - 0.5)
    )


if __name__ == "__main__":
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).with_name("live_small.db3")
    print(write(out), out.stat().st_size, "bytes")
