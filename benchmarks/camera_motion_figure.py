"""The picture of ``--camera-motion depth`` in the README: a camera approaching a wall.

The realistic approaching camera (:mod:`upsr.research.synth.realistic`, 64×56 → 256×224,
r = 4, Laplacian σ = 10 mm, seed 0) through the windowed mode registered by the flow and by
the camera's motion (:mod:`upsr.method.camera_motion`), its middle frame: the input, the
truth, both outputs, and their errors (|output − truth|, 0–100 mm; black: no depth), with
the SPEC §6 rmse and edge accuracy of the whole clip in the titles.

Example::

    .venv/bin/python benchmarks/camera_motion_figure.py --out docs/images/camera_motion.png
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

import upsr
from realistic_eval import sensor_frames
from upsr.research.metrics import evaluate
from upsr.research.synth.realistic import make_realistic
from upsr.viz.colormaps import colorbar, colorize_depth, colorize_error, panel_grid, write_png

ERROR_MAX_MM = 100.0


def outputs_grid(
    low: np.ndarray,
    truth: np.ndarray,
    outputs: dict[str, tuple[str, np.ndarray]],
    input_title: str,
    error_max_mm: float,
) -> np.ndarray:
    """One frame's picture (BGR uint8): the input (h, w) and the truth (r·h, r·w) beside a
    depth colour bar (1st and 99th percentiles of the truth), then each output's frame under
    its title, then its error |output − truth| (0–``error_max_mm``; black: no depth) beside
    an error colour bar. ``outputs``: name → (title, frame (r·h, r·w)), in display order."""
    valid = truth[truth > 0]
    vmin, vmax = float(np.percentile(valid, 1)), float(np.percentile(valid, 99))
    h = truth.shape[0]
    rows: list[list[tuple[str, np.ndarray]]] = [
        [
            (input_title, colorize_depth(low, vmin, vmax)),
            (f"truth {truth.shape[1]}x{h}", colorize_depth(truth, vmin, vmax)),
            ("", colorbar(h, vmin, vmax, "depth (mm)")),
        ],
        [],
        [],
    ]
    for name, (title, out) in outputs.items():
        rows[1].append((title, colorize_depth(out, vmin, vmax)))
        err = np.where((out > 0) & (truth > 0), np.abs(out - truth), np.nan)
        rows[2].append((f"|{name} - truth|", colorize_error(err, error_max_mm)))
    rows[1].append(("", np.full((h, 8, 3), 255, np.uint8)))
    rows[2].append(
        ("", colorbar(h, 0.0, error_max_mm, "error (mm)", colormap=cv2.COLORMAP_VIRIDIS))
    )
    return panel_grid([p for row in rows for p in row], ncols=3, min_height_px=h)


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", type=Path, default=Path("results/camera_motion.png"))
    args = p.parse_args(argv)
    video = make_realistic("toward_wall", (56, 64), scale=4, n_frames=9, seed=args.seed)
    low = sensor_frames(video, "laplace10", "laplace", 10.0, args.seed)
    c = video.camera
    outs = {
        "flow": upsr.super_resolve(low, 4, 9),
        "camera motion": upsr.super_resolve(
            low, 4, 9, camera_motion="depth", camera_intrinsics=(c.fx, c.fy, c.cx, c.cy)
        ),
    }
    t = len(low) // 2
    panels = {}
    for name, out in outs.items():
        m = evaluate(out, video.truth, 4)
        title = f"{name}: rmse {m['rmse']:.1f} mm, edge {100 * m['edge_accuracy']:.1f} %"
        print(title)
        panels[name] = (title, out[t])
    grid = outputs_grid(low[t], video.truth[t], panels, "input 64x56", ERROR_MAX_MM)
    write_png(args.out, grid)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
