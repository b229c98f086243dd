"""Accuracy and speed against the size of the flow grid (``flow_scale``) and the DIS preset of
the eq. 19 residual flows (``refine_preset``): the measurements behind their defaults.

* synthetic 64×56 ToF-like scenes (``upsr.research.synth.dynamic_scene``, wall background,
  15 frames, seeds 0–2, σ = 10 and 30 mm), r = 4, N = 9: SPEC §6 metrics averaged over the 6 videos;
* Samba 256×147 (``--data``, 20 meshes, σ = 10, 30, 50 mm), r = 4, N = 9, when the meshes are
  there: metrics and seconds per frame.

Examples
--------
::

    .venv/bin/python benchmarks/flow_grid_eval.py --out results/bench/flow_grid
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

import upsr
from upsr.research.metrics import evaluate
from upsr.research.synth import dynamic_scene

sys.path.insert(0, str(Path(__file__).resolve().parent))

from speed_eval import DEFAULT_DATA, machine, samba_frames

SETTINGS: tuple[dict[str, Any], ...] = (
    {},  # the defaults
    {"flow_scale": 2, "refine_preset": "ultrafast"},
    {"flow_scale": 3, "refine_preset": "medium"},
    {"flow_scale": 4, "refine_preset": "ultrafast"},
    {"flow_scale": 4, "refine_preset": "medium"},  # the paper's setting (flow at r)
    {"refine": False},
)
KEYS = ("surface_rmse", "edge_accuracy", "rmse", "flying_pixels")


def _name(opts: dict[str, Any]) -> str:
    return ", ".join(f"{k}={v}" for k, v in opts.items()) or "defaults"


def synthetic(settings: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    rows = []
    for opts in settings:
        acc = []
        for seed in range(3):
            for sigma in (10.0, 30.0):
                scene = dynamic_scene(
                    n_frames=15, lowres_shape=(56, 64), scale=4, noise_sigma_mm=sigma, seed=seed
                )
                m = evaluate(upsr.super_resolve(scene.lowres, 4, 9, **opts), scene.truth, 4)
                acc.append([m[k] for k in KEYS])
        mean = np.mean(acc, axis=0)
        rows.append({"options": opts, **{k: float(v) for k, v in zip(KEYS, mean, strict=True)}})
        print(
            f"synthetic {_name(opts):45s} "
            + " ".join(f"{k} {v:.4g}" for k, v in zip(KEYS, mean, strict=True)),
            flush=True,
        )
    return rows


def samba(settings: Sequence[dict[str, Any]], data: Path, cache: Path) -> list[dict[str, Any]]:
    rows = []
    for sigma in (10.0, 30.0, 50.0):
        truth, lowres = samba_frames(data, 20, sigma, cache)
        for opts in settings:
            upsr.super_resolve(lowres[:9], 4, 9, **opts)  # compile for these shapes
            start = time.perf_counter()
            out = upsr.super_resolve(lowres, 4, 9, **opts)
            seconds = (time.perf_counter() - start) / len(lowres)
            m = evaluate(out, truth, 4)
            row = {"sigma": sigma, "options": opts, "s_per_frame": seconds}
            row.update({k: float(m[k]) for k in KEYS})
            rows.append(row)
            print(
                f"Samba σ={sigma:g} {_name(opts):45s} {seconds:.3f} s/frame "
                + " ".join(f"{k} {row[k]:.4g}" for k in KEYS),
                flush=True,
            )
    return rows


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="results/bench/flow_grid")
    p.add_argument("--data", default=str(DEFAULT_DATA))
    p.add_argument("--cache", default="results/cache")
    args = p.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    res: dict[str, Any] = {"machine": machine(), "synthetic": synthetic(SETTINGS)}
    if (Path(args.data) / "samba" / "mesh_0000.obj").is_file():
        res["samba"] = samba(SETTINGS, Path(args.data), Path(args.cache))
    (out / "results.json").write_text(json.dumps(res, indent=2))
    print(f"wrote {out / 'results.json'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
