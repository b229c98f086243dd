"""A static tilted plane under a static camera: what each mode's noise does, flow or no flow.

The simplest scene there is: a plane (2000 mm + 3 mm per low-res px across, 1.5 down) seen by
a 64×56 sensor (``--shape``) that does not move, each frame with new i.i.d. Laplacian noise of
σ (``--sigma``), super-resolved by r = 4 (``--scale``), N = 9. Each mode runs with the
estimated flow (the defaults) and with a flow backend that returns zero motion (the true
motion); the rows give the RMSE (mm) over the output pixels with depth, 8 output px from the
border, of the frames after the first N, and how many pixels of those frames are 0 (every
pixel was measured). A diagnosis of the recursive mode's gap to the windowed mode at high
noise (docs/notes/recursive.md, "Noise outliers of the frame outvoted by the state").

Example::

    .venv/bin/python benchmarks/static_plane_eval.py --sigma 30
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

import upsr

__all__ = ["main", "static_plane"]


def static_plane(
    shape: tuple[int, int], scale: int, n_frames: int, sigma_mm: float, seed: int
) -> tuple[np.ndarray, np.ndarray]:
    """(truth (r·h, r·w), low-res frames (T, h, w)) of the plane, in mm."""
    h, w = shape
    rng = np.random.default_rng(seed)

    def plane(y: np.ndarray, x: np.ndarray) -> np.ndarray:
        return 2000.0 + 3.0 * x + 1.5 * y

    ys, xs = np.mgrid[0 : h * scale, 0 : w * scale].astype(np.float64)
    truth = plane((ys + 0.5) / scale - 0.5, (xs + 0.5) / scale - 0.5)
    ly, lx = np.mgrid[0:h, 0:w].astype(np.float64)
    noise = rng.laplace(0.0, sigma_mm / np.sqrt(2.0), (n_frames, h, w))
    return truth.astype(np.float32), (plane(ly, lx)[None] + noise).astype(np.float32)


def _zero_flow(first: np.ndarray, second: np.ndarray) -> np.ndarray:
    return np.zeros((*first.shape, 2), np.float32)


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sigma", type=float, default=30.0, help="Laplacian noise std (mm)")
    p.add_argument("--shape", type=int, nargs=2, default=(56, 64), metavar=("H", "W"))
    p.add_argument("--scale", type=int, default=4)
    p.add_argument("--frames", type=int, default=24)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--json", type=Path, default=None, help="also write the rows here")
    args = p.parse_args(argv)
    n, r = 9, args.scale
    truth, low = static_plane(tuple(args.shape), r, args.frames, args.sigma, args.seed)
    inner = np.zeros(truth.shape, bool)
    inner[8:-8, 8:-8] = True
    rows = []
    for mode in ("windowed", "recursive"):
        for flow, backend in (("estimated", None), ("zero", _zero_flow)):
            engine = upsr.UPSR(r, n, mode=mode, flow_backend=backend, workers=0)
            out = np.stack(list(engine.process(low)))[n:]
            valid = (out > 0) & inner
            err = (out - truth)[valid]
            row = {
                "mode": mode,
                "flow": flow,
                "rmse_mm": float(np.sqrt(np.mean(err.astype(np.float64) ** 2))),
                "zeros": int((~valid & inner).sum()),
            }
            rows.append(row)
            print(json.dumps(row), flush=True)
    if args.json is not None:
        args.json.write_text(json.dumps({"command": " ".join(sys.argv), "rows": rows}, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
