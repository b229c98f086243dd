"""Where the surface error lies: rms error by the truth's slope, per mode, on one realistic scene.

A diagnostic beside ``realistic_eval.py``: the error of the windowed mode, the recursive mode
and nearest upsampling on the pixels of each slope class of the truth (mm per output pixel:
flat < 1, gentle 1–5, slanted 5–20, steep 20–100, the box sides and floors seen at grazing
angles), over every frame of the clip; pixels more than 100 mm off (the wrong side of an
edge) are left to the edge metrics.

Example::

    .venv/bin/python benchmarks/slope_errors.py --scene toward_wall --sigma 0
    .venv/bin/python benchmarks/slope_errors.py --scene toward_wall --frames 16 --sigma 10
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

import numpy as np

import upsr
from upsr.research.synth.realistic import SCENES, degrade, make_realistic

CLASSES = ((0.0, 1.0), (1.0, 5.0), (5.0, 20.0), (20.0, 100.0))


def slope_errors(out: np.ndarray, truth: np.ndarray) -> list[tuple[int, float, float]]:
    """(pixels, rms, mean) of ``out − truth`` per slope class of :data:`CLASSES`."""
    gy, gx = np.gradient(truth, axis=(1, 2))
    slope = np.hypot(gx, gy)
    err = out - truth
    on = (out > 0) & (truth > 0) & (np.abs(err) < 100.0)
    rows = []
    for lo, hi in CLASSES:
        sel = on & (slope >= lo) & (slope < hi)
        e = err[sel]
        rows.append((int(sel.sum()), float(np.sqrt(np.mean(e**2))), float(np.mean(e))))
    return rows


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scene", default="toward_wall", choices=list(SCENES))
    p.add_argument("--sigma", type=float, default=0.0, help="Laplace noise σ (mm)")
    p.add_argument("--frames", type=int, default=9)
    p.add_argument("-n", type=int, default=9, help="N (window / recursive cap)")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    r = 4
    video = make_realistic(args.scene, (56, 64), scale=r, n_frames=args.frames, seed=args.seed)
    low = degrade(video, "laplace", np.random.default_rng(args.seed), sigma_mm=args.sigma)
    outs = {
        "windowed": upsr.super_resolve(low, r, args.n, workers=0),
        "recursive": np.stack(list(upsr.UPSR(r, args.n, mode="recursive").process(low))),
        "nearest": np.repeat(np.repeat(low, r, axis=1), r, axis=2),
    }
    print(f"{args.scene}, 64×56 → 256×224, Laplace σ = {args.sigma:g} mm, {args.frames} frames")
    print("slope (mm/px)  " + "".join(f"{m:>26s}" for m in outs))
    table = {m: slope_errors(o, video.truth) for m, o in outs.items()}
    for c, (lo, hi) in enumerate(CLASSES):
        cells = "".join(
            f"{f'{rms:.2f} ({mean:+.2f}) n={n}':>26s}"
            for n, rms, mean in (table[m][c] for m in outs)
        )
        print(f"[{lo:g}, {hi:g})".ljust(15) + cells)
    print("cells: rms error (mean error) and pixels, mm")
    return 0


if __name__ == "__main__":
    sys.exit(main())
