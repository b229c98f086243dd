"""Any frame size the validation accepts runs or is refused cleanly: never a crash.

OpenCV's DIS flow reads out of bounds (SIGSEGV, which kills the whole process) when a side of
the image at its finest pyramid level is shorter than one patch, e.g. the eq. 19 residual
flows of 9 frames of 12×128 px at r = 2. The checks run in a child process so that a crash
fails the test instead of killing the test runner.
"""

from __future__ import annotations

import subprocess
import sys

import pytest

_FLOWS = """
import numpy as np
from upsr.method.motion import make_flow_backend
rng = np.random.default_rng(0)
for preset in ("ultrafast", "fast", "medium"):
    flow = make_flow_backend("dis", preset)
    for h in (1, 2, 5, 8, 12, 16, 20, 24, 28, 31, 32):
        for w in (3, 64, 96, 128, 160, 256, 700, 1500):
            for a, b in ((h, w), (w, h)):
                im = rng.integers(0, 255, (a, b), dtype=np.uint8)
                out = flow(im, np.roll(im, 1, axis=1))
                assert out.shape == (a, b, 2) and np.isfinite(out).all(), (preset, a, b)
print("ok")
"""

_VIDEOS = """
import numpy as np, upsr
rng = np.random.default_rng(1)
for h, w, r in ((12, 128, 2), (1, 64, 2), (3, 160, 3), (7, 100, 4), (12, 64, 4), (128, 5, 2)):
    video = 1500 + rng.normal(0, 10, (9, h, w)).astype(np.float32)
    video[:, :, : w // 3] += 400  # a depth edge
    out = upsr.super_resolve(video, r, n_frames=9)
    assert out.shape == (9, r * h, r * w), out.shape
print("ok")
"""


@pytest.mark.parametrize("script", [_FLOWS, _VIDEOS], ids=["dis-sizes", "thin-videos"])
def test_thin_and_tiny_frames_do_not_crash(script: str) -> None:
    proc = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, (proc.returncode, proc.stderr[-2000:])
    assert proc.stdout.strip() == "ok"
