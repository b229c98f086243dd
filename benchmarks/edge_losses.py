"""Where the edges go wrong: edge pixels each mode loses and wins against nearest, per frame.

A diagnostic beside ``realistic_eval.py``: on the pixels within r of a depth edge of the truth
(the edge-accuracy pixels, SPEC §6), those nearest upsampling puts within the edge tolerance
and a mode of upsr does not ("lost") and the other way round ("won"), frame by frame, and of
the lost ones how many the output puts nearer than the truth (a foreground grown over its
background) or farther. A mode's edge accuracy is nearest's plus (won − lost) / pixels.

Example (the approaching camera twice as fast, where the recursive mode loses its edges)::

    .venv/bin/python benchmarks/edge_losses.py --scene toward_wall --scene-option speed_mm=50 \\
        --sensor gaussian --sigma 20 --seed 2
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

import upsr
from upsr.research import baselines
from upsr.research.metrics import EDGE_TOLERANCE_MM, near_discontinuity
from upsr.research.synth.realistic import SCENES, make_realistic

sys.path.insert(0, str(Path(__file__).resolve().parent))
from realistic_eval import scene_options, sensor_frames


def edge_losses(out: np.ndarray, near: np.ndarray, truth: np.ndarray, r: int) -> dict:
    """Per frame: edge pixels lost and won against ``near``, and the lost ones' side."""
    edge = np.stack([(t > 0) & near_discontinuity(t, r) for t in truth])
    good_out = (out > 0) & (np.abs(out - truth) <= EDGE_TOLERANCE_MM)
    good_near = (near > 0) & (np.abs(near - truth) <= EDGE_TOLERANCE_MM)
    lost = edge & good_near & ~good_out
    won = edge & good_out & ~good_near
    nearer = lost & (out > 0) & (out < truth)
    return {
        "edge": edge.sum(axis=(1, 2)),
        "lost": lost.sum(axis=(1, 2)),
        "won": won.sum(axis=(1, 2)),
        "nearer": nearer.sum(axis=(1, 2)),
        "none": (lost & (out <= 0)).sum(axis=(1, 2)),
    }


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scene", default="toward_wall", choices=list(SCENES))
    p.add_argument("--scene-option", action="append", default=[], metavar="NAME=VALUE")
    p.add_argument("--sensor", default="laplace", choices=("laplace", "gaussian", "tof", "kinect"))
    p.add_argument("--sigma", type=float, default=10.0, help="noise σ (mm)")
    p.add_argument("--frames", type=int, default=9)
    p.add_argument("-n", type=int, default=9, help="N (window / recursive cap)")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    # realistic_eval.py's sizes: the Kinect model at 160×120, r = 2; the others at 64×56, r = 4
    shape, r = ((120, 160), 2) if args.sensor == "kinect" else ((56, 64), 4)
    video = make_realistic(
        args.scene, shape, scale=r, n_frames=args.frames, seed=args.seed,
        **scene_options(args.scene_option),
    )  # fmt: skip
    # the same noise as realistic_eval.py's row of this sensor and σ
    label = {"laplace": "laplace", "gaussian": "gauss", "tof": "tof", "kinect": "kinect"}
    label = label[args.sensor] + ("" if args.sensor == "kinect" else f"{args.sigma:g}")
    sigma = 0.0 if args.sensor == "kinect" else args.sigma  # as realistic_eval.py
    low = sensor_frames(video, label, args.sensor, sigma, args.seed)
    near = baselines.nearest(low, r)
    size = f"{shape[1]}×{shape[0]} → {shape[1] * r}×{shape[0] * r}"
    print(f"{args.scene} {args.scene_option}, {size}, {label}, seed {args.seed}")
    for mode in ("windowed", "recursive"):
        out = upsr.super_resolve(low, r, args.n, mode=mode)
        t = edge_losses(out, near, video.truth, r)
        pairs = " ".join(f"{a}/{b}" for a, b in zip(t["lost"], t["won"], strict=True))
        lost, won, total = int(t["lost"].sum()), int(t["won"].sum()), int(t["edge"].sum())
        print(f"{mode:10s} lost/won per frame: {pairs}")
        print(
            f"{'':10s} lost {lost}, won {won} of {total} edge pixels "
            f"({100 * (won - lost) / total:+.2f} points against nearest); of the lost "
            f"{int(t['nearer'].sum())} nearer than the truth, {int(t['none'].sum())} without depth"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
