"""Thin parts on a ToF sensor: random bars narrower than a pixel, with and without the split.

A scene not tuned to: per seed three elliptic bodies (1.2–2.6 m) drift in front of a wall at
3.5 m, each with three bars 0.3–0.9 low-res px wide and 30–70 high-res px long growing out of
its rim at random angles (any orientation, turning slowly), 80 mm in front of or behind the
body at most; ToF footprints (each 64×56 pixel the mean of its 4×4 block), Gaussian noise
σ = 10 mm, 9 frames. Per seed, nearest upsampling and both modes of UP-SR with the defaults
and with ``thin_parts=False`` (the parts left as measured, :mod:`upsr.method.thin`), scored
with SPEC §6 (rmse, edge accuracy, flying pixels, missing depth).

Example::

    .venv/bin/python benchmarks/thin_parts_eval.py --seeds 0 1 2 3 4 5 --out docs/results/thin_parts
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

import upsr
from upsr.research import baselines
from upsr.research.metrics import evaluate
from upsr.research.synth.degradation import tof_footprint

R, LOW_SHAPE, N_FRAMES, WALL_MM, SIGMA_MM = 4, (56, 64), 9, 3500.0, 10.0
METRICS = ("rmse", "edge_accuracy", "flying_pixels", "missing")


def thin_bars_scene(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(truth (T, 224, 256), ToF frames (T, 56, 64)) of one seed, in mm."""
    rng = np.random.default_rng(seed)
    hh, ww = LOW_SHAPE[0] * R, LOW_SHAPE[1] * R
    yy, xx = np.mgrid[0:hh, 0:ww] + 0.5
    bodies = []
    for _ in range(3):
        body = {
            "cy": rng.uniform(0.2 * hh, 0.8 * hh),
            "cx": rng.uniform(0.2 * ww, 0.8 * ww),
            "ry": rng.uniform(12, 28),
            "rx": rng.uniform(12, 28),
            "z": rng.uniform(1200, 2600),
            "vy": rng.uniform(-3, 3),
            "vx": rng.uniform(-3, 3),
        }
        body["bars"] = [
            {
                "angle": rng.uniform(0, 2 * math.pi),
                "length": rng.uniform(30, 70),
                "width": rng.uniform(0.3, 0.9) * R,
                "dz": rng.uniform(-80, 80),
            }
            for _ in range(3)
        ]
        bodies.append(body)
    frames = []
    for t in range(N_FRAMES):
        z = np.full((hh, ww), WALL_MM)
        for body in sorted(bodies, key=lambda b: -b["z"]):  # far to near
            cy, cx = body["cy"] + body["vy"] * t, body["cx"] + body["vx"] * t
            inside = ((yy - cy) / body["ry"]) ** 2 + ((xx - cx) / body["rx"]) ** 2 <= 1
            z[inside] = body["z"]
            for bar in body["bars"]:
                a = bar["angle"] + 0.02 * t
                ux, uy = math.cos(a), math.sin(a)
                along = (xx - cx) * ux + (yy - cy) * uy
                across = np.abs(-(xx - cx) * uy + (yy - cy) * ux)
                rim = 1.0 / math.sqrt((ux / body["rx"]) ** 2 + (uy / body["ry"]) ** 2)
                bar_px = (along > 0.8 * rim) & (along < rim + bar["length"]) & ~inside
                z[bar_px & (across < bar["width"] / 2)] = body["z"] + bar["dz"]
        frames.append(z)
    truth = np.stack(frames).astype(np.float32)
    low = tof_footprint(truth, R) + rng.normal(0, SIGMA_MM, (N_FRAMES, *LOW_SHAPE))
    return truth, low.astype(np.float32)


def run_seed(seed: int) -> dict[str, dict[str, float]]:
    """The metrics of every method on one seed's scene."""
    truth, low = thin_bars_scene(seed)
    methods = {"nearest": lambda: baselines.nearest(low, R)}
    for mode in ("windowed", "recursive"):
        for thin in (True, False):
            name = mode + ("" if thin else "_no_thin_parts")
            methods[name] = lambda m=mode, s=thin: upsr.super_resolve(
                low, R, N_FRAMES, mode=m, thin_parts=s
            )
    out = {}
    for name, fn in methods.items():
        m = evaluate(fn(), truth, R)
        out[name] = {k: float(m[k]) for k in METRICS}
    return out


def _table(results: dict[int, dict[str, dict[str, float]]]) -> str:
    lines = [
        "| seed | method | rmse (mm) | edge accuracy (%) | flying (%) | missing (%) |",
        "|---|---|---|---|---|---|",
    ]
    for seed, rows in results.items():
        for name, m in rows.items():
            lines.append(
                f"| {seed} | {name} | {m['rmse']:.1f} | {100 * m['edge_accuracy']:.2f} | "
                f"{100 * m['flying_pixels']:.2f} | {100 * m['missing']:.2f} |"
            )
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4, 5])
    p.add_argument("--out", default="results/thin_parts")
    args = p.parse_args(argv)
    results = {}
    for seed in args.seeds:
        results[seed] = run_seed(seed)
        print(f"seed {seed} done", flush=True)
    table = _table(results)
    print(table)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    command = "benchmarks/thin_parts_eval.py --seeds " + " ".join(map(str, args.seeds))
    (out / "results.json").write_text(
        json.dumps({"command": command, "results": results}, indent=2)
    )
    (out / "results.md").write_text(
        f"# Thin parts on a ToF sensor\n\n`{command} --out {args.out}`\n\n"
        f"{__doc__.split(chr(10) + chr(10))[1]}\n\n{table}\n"
    )
    print(f"wrote {out / 'results.json'} and results.md")
    return 0


if __name__ == "__main__":
    sys.exit(main())
