"""A sensor's stray far values against ``--valid-range`` (``UPSRConfig.valid_range_mm``).

A 12-frame 64×56 room seen by a moving camera (:mod:`upsr.research.synth.realistic`, Laplace
σ = 10 mm, in whole mm as a 16-bit sensor gives it), then 1 % of its pixels set to 65535 mm (a
RealSense camera's largest value), super-resolved at r = 2 by both modes with and without
``valid_range_mm = (100, 10000)``, and the same video without strays: rmse over the output's
valid pixels against the truth, the share of the output beyond 10 m and the share at 0. The
engine's output equals ``upsr run IN.npy -o OUT.npy -r 2 [--recursive] [--valid-range
100,10000]`` on the same frames (``tests/apps/cli/test_batch.py``).

Example::

    .venv/bin/python benchmarks/stray_eval.py --out docs/results/stray
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

import upsr
from upsr.research.synth.realistic import degrade, make_realistic

__all__ = ["main"]

RANGE_MM = (100.0, 10000.0)


def main(argv: Sequence[str] | None = None) -> dict[str, Any]:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--share", type=float, default=0.01, help="share of stray pixels")
    p.add_argument("--out", type=Path, default=Path("results/bench/stray"))
    args = p.parse_args(argv)
    video = make_realistic("room", (56, 64), scale=2, n_frames=12)
    clean = np.round(degrade(video, "laplace", np.random.default_rng(0), sigma_mm=10.0))
    stray = clean.copy()
    stray[np.random.default_rng(1).random(stray.shape) < args.share] = 65535.0
    rows = []
    for label, frames in (("strays", stray), ("no strays", clean)):
        for mode in ("windowed", "recursive"):
            for valid_range in (None, RANGE_MM):
                if label == "no strays" and valid_range is not None:
                    continue
                out = upsr.super_resolve(frames, 2, 9, mode=mode, valid_range_mm=valid_range)
                ok = (out > 0) & (video.truth > 0)
                rows.append(
                    {
                        "input": label,
                        "mode": mode,
                        "valid_range_mm": valid_range,
                        "rmse": float(np.sqrt(np.mean((out[ok] - video.truth[ok]) ** 2))),
                        "beyond_10m_pct": 100.0 * float((out > 10000).mean()),
                        "zero_pct": 100.0 * float((out == 0).mean()),
                    }
                )
    lines = [
        f"stray far values ({100 * args.share:g} % of the pixels at 65535 mm), 64×56 room, r = 2",
        "",
        "| input | mode | --valid-range | rmse (mm) | output > 10 m | output 0 |",
        "|---|---|---|---|---|---|",
    ]
    for row in rows:
        vr = "–" if row["valid_range_mm"] is None else "{:g},{:g}".format(*row["valid_range_mm"])
        lines.append(
            f"| {row['input']} | {row['mode']} | {vr} | {row['rmse']:.1f} | "
            f"{row['beyond_10m_pct']:.3f} % | {row['zero_pct']:.2f} % |"
        )
    print("\n".join(lines))
    args.out.mkdir(parents=True, exist_ok=True)
    result = {"share": args.share, "rows": rows}
    (args.out / "results.json").write_text(json.dumps(result, indent=2))
    (args.out / "results.md").write_text("\n".join(lines) + "\n")
    return result


if __name__ == "__main__":
    main()
