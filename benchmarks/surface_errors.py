"""Where the surface error lies: creases, slopes and flat surfaces, per mode and window.

A diagnostic beside ``recursive_eval.py``: the surface pixels of SPEC §6 (valid in the truth,
farther than r output px from a depth discontinuity) of the frames after the first N are
split into

* crease pixels: within r px of a bend of the truth (a second difference along a row or a
  column above ``--crease-mm``, 3 mm per output px²: a box's top meeting its front, a floor
  meeting a wall);
* slope pixels: the others whose truth slopes by at least ``--slope-mm`` (5 mm) per output
  px;
* flat pixels: the rest;

and for each mode and N the rmse of each group and its share of the squared error is printed.
The scenes are :mod:`upsr.research.synth.realistic`'s, under Laplacian noise of ``--sigma``.

Example (the approaching camera at 160×120 → 320×240: most of the surface error lies at its
creases, and the recursive mode's state makes its slopes worse than one frame alone)::

    .venv/bin/python benchmarks/surface_errors.py --scenes toward_wall --sizes qvga \\
        --frames 14 --modes windowed recursive --n 1 3 9
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

import numpy as np
from scipy import ndimage

import upsr
from upsr.research.metrics import near_discontinuity
from upsr.research.synth.realistic import SCENES, degrade, make_realistic

SIZES = {"tof": ((56, 64), 4), "qvga": ((120, 160), 2), "vga": ((240, 320), 2)}
GROUPS = ("crease", "slope", "flat")


def surface_groups(
    truth: np.ndarray, r: int, crease_mm: float = 3.0, slope_mm: float = 5.0
) -> dict[str, np.ndarray]:
    """The crease, slope and flat surface pixels (bool (h, w) each) of one true frame (h, w)
    at the SR factor ``r`` (see the module)."""
    t = np.asarray(truth, np.float64)
    surface = (t > 0) & ~near_discontinuity(t, r)
    bend = np.zeros(t.shape)
    for axis in (0, 1):
        edge = np.take(t, [0], axis=axis), np.take(t, [-1], axis=axis)
        bend = np.maximum(bend, np.abs(np.diff(t, 2, axis=axis, prepend=edge[0], append=edge[1])))
    crease = surface & (ndimage.maximum_filter(bend, 2 * r + 1) > crease_mm)
    gy, gx = np.gradient(t)
    slope = surface & ~crease & (np.hypot(gy, gx) >= slope_mm)
    return {"crease": crease, "slope": slope, "flat": surface & ~crease & ~slope}


def group_errors(
    estimate: np.ndarray, truth: np.ndarray, r: int, first: int, **kw: float
) -> dict[str, tuple[int, float, float]]:
    """(pixels, rmse mm, share of the squared error) of each group over the frames from
    ``first`` on, where the estimate has depth."""
    sq = dict.fromkeys(GROUPS, 0.0)
    count = dict.fromkeys(GROUPS, 0)
    for est, tru in zip(estimate[first:], truth[first:], strict=True):
        err = est.astype(np.float64) - tru
        for name, mask in surface_groups(tru, r, **kw).items():
            m = mask & (est > 0)
            sq[name] += float(np.sum(err[m] ** 2))
            count[name] += int(m.sum())
    total = sum(sq.values()) or 1.0
    return {
        g: (count[g], float(np.sqrt(sq[g] / count[g])) if count[g] else 0.0, sq[g] / total)
        for g in GROUPS
    }


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenes", nargs="+", default=["toward_wall"], choices=list(SCENES))
    p.add_argument("--sizes", nargs="+", default=["qvga"], choices=list(SIZES))
    p.add_argument("--frames", type=int, default=14, help="video length T")
    p.add_argument("--n", nargs="+", type=int, default=[9], help="N (window / recursive cap)")
    p.add_argument("--modes", nargs="+", default=["windowed", "recursive"])
    p.add_argument("--sigma", type=float, default=10.0, help="Laplacian noise σ (mm)")
    p.add_argument("--crease-mm", type=float, default=3.0)
    p.add_argument("--slope-mm", type=float, default=5.0)
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    kw = {"crease_mm": args.crease_mm, "slope_mm": args.slope_mm}
    for size in args.sizes:
        shape, r = SIZES[size]
        for scene in args.scenes:
            video = make_realistic(scene, shape, scale=r, n_frames=args.frames, seed=args.seed)
            rng = np.random.default_rng(args.seed)
            low = degrade(video, "laplace", rng, sigma_mm=args.sigma)
            first = min(max(args.n), args.frames - 1)
            print(f"{scene} {size} σ = {args.sigma:g} mm, frames {first}–{args.frames - 1}")
            for mode in args.modes:
                for n in args.n:
                    out = upsr.super_resolve(low, r, n, mode=mode)
                    res = group_errors(out, video.truth, r, first, **kw)
                    sq = sum(res[g][0] * res[g][1] ** 2 for g in GROUPS)
                    px = sum(res[g][0] for g in GROUPS)
                    cells = "  ".join(
                        f"{g} {res[g][1]:6.3f} ({100 * res[g][2]:4.1f} %)" for g in GROUPS
                    )
                    print(f"  {mode:9s} N = {n}: all {np.sqrt(sq / max(px, 1)):6.3f}  {cells}")
            shares = surface_groups(video.truth[first], r, **kw)
            pixels = sum(int(m.sum()) for m in shares.values()) or 1
            print("  pixels: " + ", ".join(
                f"{g} {100 * int(m.sum()) / pixels:.1f} %" for g, m in shares.items()
            ))  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
