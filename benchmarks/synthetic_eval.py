"""Accuracy benchmark on the built-in synthetic dynamic scenes (no external data needed).

A slanted wall (or no background: depth 0, "no return") with a moving, breathing blob and a
rotating arm (:func:`upsr.research.synth.dynamic_scene`) is point-sampled at low resolution with
Laplacian noise of std σ and super-resolved by the command line exactly as a user would run
it (``upsr run lowres.npy -o out.npy --scale r``). Nearest and bicubic upsampling are the
baselines; every method is scored with the SPEC §6 metrics (:func:`upsr.research.metrics.evaluate`),
pooled over all frames. The acceptance criteria of issue #2 are checked and printed per case:

* surface RMSE ≤ 0.3·σ (σ > 0),
* edge accuracy ≥ nearest's,
* flying pixels < 1 %,
* invented depth ≤ nearest's,
* RMSE below nearest's and bicubic's (σ ≥ 10 mm).

Example::

    .venv/bin/python benchmarks/synthetic_eval.py --scale 2 4 --sigma 0 10 30 50
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from samba_eval import print_table, run_upsr_cli, write_results
from upsr.research import baselines
from upsr.research.metrics import evaluate
from upsr.research.synth import dynamic_scene

__all__ = ["check_criteria", "main"]


def check_criteria(rows: dict[str, dict[str, float]], sigma: float) -> dict[str, bool]:
    """The acceptance criteria of issue #2 for one case (``rows[method] = metrics``)."""
    up, near, bic = rows["upsr"], rows["nearest"], rows["bicubic"]
    checks = {
        "surface<=0.3sigma": sigma == 0 or up["surface_rmse"] <= 0.3 * sigma,
        "edge>=nearest": up["edge_accuracy"] >= near["edge_accuracy"],
        "flying<1%": up["flying_pixels"] < 0.01,
        "invented<=nearest": up["invented"] <= near["invented"],
    }
    if sigma >= 10:
        checks["rmse<nearest,bicubic"] = up["rmse"] < min(near["rmse"], bic["rmse"])
    return checks


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scale", "-r", type=int, nargs="+", default=[2, 4])
    p.add_argument("--sigma", type=float, nargs="+", default=[0.0, 10.0, 30.0, 50.0])
    p.add_argument("--background", nargs="+", default=["wall", "none"], choices=["wall", "none"])
    p.add_argument("--frames", "-n", type=int, default=9, help="window length N")
    p.add_argument("--n-frames-total", type=int, default=15)
    p.add_argument("--lowres-height", type=int, default=48)
    p.add_argument("--lowres-width", type=int, default=64)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default="results/synthetic_eval")
    args = p.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows: list[dict] = []
    failures = []
    with tempfile.TemporaryDirectory() as tmp:
        for bg in args.background:
            for r in args.scale:
                for sigma in args.sigma:
                    shape = (args.lowres_height * 4 // r, args.lowres_width * 4 // r)
                    scene = dynamic_scene(
                        n_frames=args.n_frames_total,
                        lowres_shape=shape,
                        scale=r,
                        noise_sigma_mm=sigma,
                        background=bg,
                        seed=args.seed,
                    )
                    lr_path = Path(tmp) / "lowres.npy"
                    np.save(lr_path, scene.lowres)
                    up, seconds, _ = run_upsr_cli(
                        lr_path, Path(tmp) / "upsr.npy", r, args.frames, []
                    )
                    case = {
                        "nearest": evaluate(baselines.nearest(scene.lowres, r), scene.truth, r),
                        "bicubic": evaluate(baselines.bicubic(scene.lowres, r), scene.truth, r),
                        "upsr": evaluate(up, scene.truth, r),
                    }
                    checks = check_criteria(case, sigma)
                    failed = [k for k, ok in checks.items() if not ok]
                    if failed:
                        failures.append(f"background={bg} r={r} sigma={sigma:g}: {failed}")
                    for method, m in case.items():
                        rows.append(
                            {
                                "sigma": sigma,
                                "method": f"{method} {bg} r{r}",
                                **m,
                                "seconds": seconds if method == "upsr" else 0.0,
                                "background": bg,
                                "scale": r,
                                "criteria_failed": ";".join(failed) if method == "upsr" else "",
                            }
                        )
    rows.sort(key=lambda row: (row["sigma"], row["background"], row["scale"]))
    print_table(rows)
    write_results(rows, vars(args), out)
    print(f"\nwrote {out / 'results.json'} and {out / 'results.csv'}")
    print("criteria failed:" if failures else "all criteria met", *failures, sep="\n  ")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
