"""The picture of the final smoothing along each surface's plane in the README.

The outside audit's static ``slanted`` scene (:func:`outside_scenes.slanted`: a static camera
before a wall yawed 50°, a floor seen at a grazing angle and a tilted panel; 64×56 → 256×224,
r = 4, Laplacian σ = 10 mm, 15 frames, the noise of ``benchmarks/outside_eval.py``'s row)
through the windowed mode without the final smoothing (``--smooth-mm 0``) and with it (the
default), its middle frame: the input, the truth, both outputs, and their errors
(|output − truth|, 0–``--error-max`` mm; black: no depth), with the static surface rmse of the
whole clip (``realistic_eval.score``) in the titles.

Example::

    .venv/bin/python benchmarks/smoothing_figure.py --out docs/images/plane_smoothing.png
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

import upsr
from camera_motion_figure import outputs_grid
from outside_eval import LAPLACE10, sensor_input
from outside_scenes import slanted
from realistic_eval import score
from upsr.viz.colormaps import write_png


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--error-max", type=float, default=15.0, help="error colour scale (mm)")
    p.add_argument("--out", type=Path, default=Path("results/plane_smoothing.png"))
    args = p.parse_args(argv)
    video = slanted((56, 64), 4, 15)
    low = sensor_input(video, "slanted", LAPLACE10, args.seed)
    outs = {
        "--smooth-mm 0": upsr.super_resolve(low, 4, 9, deblur_smooth_sigma_mm=None),
        "default": upsr.super_resolve(low, 4, 9),
    }
    t = len(low) // 2
    panels = {}
    for name, out in outs.items():
        title = f"{name}: static surfaces {score(out, video)['surface_static']:.2f} mm rmse"
        print(title)
        panels[name] = (title, out[t])
    grid = outputs_grid(
        low[t], video.truth[t], panels, "input 64x56, Laplace 10 mm", args.error_max
    )
    write_png(args.out, grid)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
