"""What the spurious-motion suppression (``UPSRConfig.zero_motion_tolerance``) gains and costs.

Two scenes, each super-resolved with the suppression on (default) and off:

* a smooth body drifting sideways: the Samba dancer (meshes 0–10) moved 40 mm per frame,
  truth 512², input 512²/r, Laplacian noise σ = 30 mm (needs ``--data``);
* a static slanted wall behind a moving object: :func:`upsr.research.synth.dynamic_scene`, r = 4,
  σ = 30 mm.

Prints the SPEC §6 metrics (frames 3–7 pooled) of each run::

    .venv/bin/python benchmarks/motion_suppression_eval.py --data ../shared/data
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import upsr
from upsr.research.metrics import evaluate
from upsr.research.synth import add_laplacian_noise, dynamic_scene

SETTINGS = {"suppression on": {}, "suppression off": {"zero_motion_tolerance": None}}
KEYS = ("rmse", "surface_rmse", "edge_accuracy", "flying_pixels", "invented")


def _report(name: str, lowres: np.ndarray, truth: np.ndarray, r: int) -> None:
    for label, opts in SETTINGS.items():
        out = upsr.super_resolve(lowres, r, 9, **opts)
        m = evaluate(out[3:8], truth[3:8], r)
        print(f"{name:28s} r={r} {label:16s}", "  ".join(f"{k}={m[k]:.3f}" for k in KEYS))


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", default=str(Path(__file__).resolve().parents[2] / "shared" / "data"))
    args = p.parse_args()
    if (Path(args.data) / "samba").is_dir():
        from upsr.research.experiments.data import render_samba, samba_mesh_paths

        paths = samba_mesh_paths(args.data, 0, 11)
        rend = render_samba(paths, width=512, height=512, scales=(1, 4), lateral_mm_per_frame=40)
        for k, r in enumerate((1, 4)):
            lr = rend.lowres[r] if isinstance(rend.lowres, dict) else rend.lowres[k]
            noisy = add_laplacian_noise(lr, 30.0, np.random.default_rng(0))
            _report("Samba drifting 40 mm/frame", noisy, rend.truth, r)
    scene = dynamic_scene(n_frames=15, lowres_shape=(48, 64), scale=4, noise_sigma_mm=30.0)
    _report("synthetic wall scene", scene.lowres, scene.truth, 4)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
