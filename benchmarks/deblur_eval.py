"""The last steps of UP-SR on fused frames: deblurring iterations and speckle removal.

For each scene, UP-SR's fused frames (``deblur=False``, no speckle removal) are computed once;
then

* the deblurring (:func:`upsr.method.deblurring.deblur`, defaults but ``iterations``) is run with
  10, 15 (the default), 20 and 30 subgradient steps: the objective of eq. 30 (mean over every
  4th frame, without the final surface smoothing) and the SPEC §6 metrics of the output;
* the speckle removal (:func:`upsr.method.outliers.remove_speckles`, r² px, 100 mm) is switched off
  and on after the default deblurring: pixels removed and SPEC §6 metrics.

Scenes: Samba meshes 0–12 (256×147 → 1024×588, r = 4, N = 9) at σ = 10, 30, 60, 100 mm (needs
``--data``), and the synthetic ToF scene of the speed benchmark (64×56, r = 4, σ = 20 mm,
30 frames)::

    .venv/bin/python benchmarks/deblur_eval.py --data ../shared/data --out docs/results/deblur
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np

import upsr
from upsr.method.config import DeblurConfig, UPSRConfig
from upsr.method.deblurring import deblur, deblur_energy
from upsr.method.outliers import remove_speckles
from upsr.research.metrics import evaluate
from upsr.research.synth import add_laplacian_noise, dynamic_scene

ITERATIONS = (10, 15, 20, 30)
SAMBA_SIGMAS = (10.0, 30.0, 60.0, 100.0)
KEYS = ("mse", "rmse", "surface_rmse", "edge_accuracy", "flying_pixels", "missing")


def _metrics(out: np.ndarray, truth: np.ndarray, r: int) -> dict[str, float]:
    m = evaluate(out, truth, r)
    return {k: float(m[k]) for k in KEYS}


def scene_rows(name: str, lowres: np.ndarray, truth: np.ndarray, r: int) -> list[dict[str, Any]]:
    """Every deblurring / speckle variant on one scene."""
    fused = np.stack(list(upsr.UPSR(r, 9, deblur=False, speckle_px=0).process(lowres)))
    rows: list[dict[str, Any]] = []
    base = DeblurConfig()
    for it in ITERATIONS:
        cfg = dataclasses.replace(base, iterations=it)
        plain = dataclasses.replace(cfg, smooth_sigma_mm=None)
        energy = float(
            np.mean([deblur_energy(deblur(f, plain, scale=r), f, plain, r) for f in fused[::4]])
        )
        out = np.stack([deblur(f, cfg, scale=r) for f in fused])
        rows.append(
            {"scene": name, "variant": f"iterations={it}", "energy": energy}
            | _metrics(out, truth, r)
        )
    deblurred = np.stack([deblur(f, base, scale=r) for f in fused])
    size, edge = UPSRConfig(scale=r).speckle_size_px, UPSRConfig().edge_mm
    cleaned = np.stack([remove_speckles(f, size, edge) for f in deblurred])
    for variant, out in (("speckles kept", deblurred), ("speckles removed", cleaned)):
        removed = int(np.count_nonzero((deblurred > 0) & (out == 0)))
        rows.append(
            {"scene": name, "variant": variant, "removed_px": removed} | _metrics(out, truth, r)
        )
    return rows


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", default=str(Path(__file__).resolve().parents[2] / "shared" / "data"))
    p.add_argument("--out", default="results/bench/deblur")
    args = p.parse_args(argv)
    rows: list[dict[str, Any]] = []
    tof = dynamic_scene(n_frames=30, lowres_shape=(56, 64), scale=4, noise_sigma_mm=20.0, seed=0)
    rows += scene_rows("ToF 64x56 sigma=20", tof.lowres, tof.truth, 4)
    if (Path(args.data) / "samba" / "mesh_0000.obj").is_file():
        from upsr.research.experiments.data import render_samba, samba_mesh_paths

        rendered = render_samba(
            samba_mesh_paths(Path(args.data), 0, 13), width=1024, height=588, scales=(1, 4)
        )
        for sigma in SAMBA_SIGMAS:
            noisy = add_laplacian_noise(rendered.lowres[4], sigma, rng=np.random.default_rng(0))
            rows += scene_rows(f"Samba sigma={sigma:g}", noisy, rendered.truth, 4)
    print(
        f"{'scene':20s} {'variant':17s} {'energy':>10s} {'removed':>8s} "
        + " ".join(f"{k:>13s}" for k in KEYS)
    )
    for row in rows:
        energy = f"{row['energy']:10.0f}" if "energy" in row else " " * 10
        removed = f"{row['removed_px']:8d}" if "removed_px" in row else " " * 8
        print(
            f"{row['scene']:20s} {row['variant']:17s} {energy} {removed} "
            + " ".join(f"{row[k]:13.5f}" for k in KEYS),
            flush=True,
        )
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "results.json").write_text(json.dumps({"rows": rows}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
