"""Recursive against windowed UP-SR on dense scenes: frames/s, stage times and accuracy.

Scenes (``--scenes``, default the room): :mod:`upsr.research.synth.realistic` (the room seen by
a moving camera, every pixel measured; the deforming body, the camera toward a wall, the
galloping animal), Laplacian noise of σ = 10 mm (``--sensor``, ``--sigma``), at the ToF
size 64×56 → 256×224 (r = 4), 160×120 → 320×240 and 320×240 → 640×480 (r = 2). Per size,
both modes run on the same frames with the defaults (windowed: one window at a time,
``workers=0``, and with the default workers; ``--camera-motion depth``: registered by the
camera's motion, with the scene's intrinsics); the rate is measured after a warm-up frame
(numba compiled, caches filled), the stages from the engine's ``timings``, the accuracy
(SPEC §6) on the frames after the first N.

Example::

    .venv/bin/python benchmarks/recursive_eval.py --frames 24
    .venv/bin/python benchmarks/recursive_eval.py --scenes deforming room toward_wall gallop \
        --sizes tof --frames 16
    .venv/bin/python benchmarks/recursive_eval.py --sizes tof --frames 40 --flow-preset fast
    .venv/bin/python benchmarks/recursive_eval.py --sizes vga --modes recursive --flow-scale 2
    .venv/bin/python benchmarks/recursive_eval.py --scenes deforming room toward_wall gallop \
        --sizes tof qvga --frames 24 --modes recursive windowed causal
    .venv/bin/python benchmarks/recursive_eval.py --scenes toward_wall --sizes tof qvga \
        --frames 24 --sensor gaussian --sigma 20 --camera-motion depth
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
import time
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np

import upsr
from upsr.method import windowed
from upsr.research.metrics import evaluate
from upsr.research.synth.realistic import SCENES, degrade, make_realistic

SIZES = {"tof": ((56, 64), 4), "qvga": ((120, 160), 2), "vga": ((240, 320), 2)}


@contextlib.contextmanager
def causal_windows() -> Iterator[None]:
    """The windowed engine with each window ending at its reference (latency 0, the frames
    the recursive mode has seen): the ``causal`` mode of this benchmark, a diagnostic."""
    start = windowed.window_start
    windowed.window_start = lambda t, n_total, cfg: int(  # type: ignore[assignment]
        min(max(t - (cfg.n_frames - 1), 0), n_total - cfg.n_frames)
    )
    try:
        yield
    finally:
        windowed.window_start = start  # type: ignore[assignment]


def _run(mode: str, low: np.ndarray, r: int, n: int, workers: int, options: dict) -> dict:
    causal = mode == "causal"
    cfg = upsr.UPSRConfig.from_options(r, n, mode="windowed" if causal else mode, **options)
    with causal_windows() if causal else contextlib.nullcontext():
        warm = upsr.UPSR(config=cfg, workers=workers)
        list(warm.process(low[: n + 1]))  # compile and fill the caches
        engine = upsr.UPSR(config=cfg, workers=workers)
        start = time.perf_counter()
        out = np.stack(list(engine.process(low)))
        seconds = time.perf_counter() - start
    per_frame = {k: 1000.0 * v / len(low) for k, v in engine.timings.items()}
    return {"out": out, "fps": len(low) / seconds, "ms_per_frame": per_frame}


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", nargs="+", default=["tof", "vga"], choices=list(SIZES))
    p.add_argument("--scenes", nargs="+", default=["room"], choices=list(SCENES))
    p.add_argument("--frames", type=int, default=24, help="video length T")
    p.add_argument("-n", type=int, default=9, help="N (window / recursive cap)")
    p.add_argument("--sigma", type=float, default=10.0)
    p.add_argument(
        "--modes", nargs="+", default=["recursive", "windowed"],
        choices=["recursive", "windowed", "causal"],
        help="causal: the windowed mode with windows that end at their reference (a diagnostic)",
    )  # fmt: skip
    p.add_argument("--workers", type=int, default=0, help="windowed workers")
    p.add_argument("--flow-preset", default=None)
    p.add_argument("--flow-scale", type=int, default=None, help="flow grid scale s (default: auto)")
    p.add_argument("--iterations", type=int, default=None, help="deblur iterations")
    p.add_argument("--step-decay", type=float, default=None, help="deblur step decay")
    p.add_argument("--estimator", default=None, help="fusion_estimator (default: auto)")
    p.add_argument("--sensor", default="laplace", choices=["laplace", "gaussian"])
    p.add_argument(
        "--camera-motion", default="flow", choices=["flow", "depth"],
        help="camera_motion (depth: with the scene's intrinsics)",
    )  # fmt: skip
    p.add_argument("--json", type=Path, default=None)
    args = p.parse_args(argv)
    options: dict = {}
    if args.flow_preset:
        options["flow_preset"] = args.flow_preset
    if args.flow_scale is not None:
        options["flow_scale"] = args.flow_scale
    if args.iterations is not None:
        options["deblur_iterations"] = args.iterations
    if args.step_decay is not None:
        options["deblur_step_decay"] = args.step_decay
    if args.estimator is not None:
        options["fusion_estimator"] = args.estimator
    rows = []
    for scene, size in ((scene, size) for scene in args.scenes for size in args.sizes):
        shape, r = SIZES[size]
        video = make_realistic(scene, shape, scale=r, n_frames=args.frames)
        low = degrade(video, args.sensor, np.random.default_rng(0), sigma_mm=args.sigma)
        if args.camera_motion == "depth":
            c = video.camera
            options.update(camera_motion="depth", camera_intrinsics=(c.fx, c.fy, c.cx, c.cy))
        for mode in args.modes:
            res = _run(mode, low, r, args.n, args.workers, options)
            sl = slice(args.n, None)
            m = evaluate(res["out"][sl], video.truth[sl], r)
            row = {
                "scene": scene,
                "size": f"{shape[1]}x{shape[0]}->{shape[1] * r}x{shape[0] * r} (r={r})",
                "mode": mode,
                "fps": round(res["fps"], 1),
                **{f"{k}_ms": round(v, 1) for k, v in res["ms_per_frame"].items()},
                **{k: round(float(m[k]), 4) for k in ("surface_rmse", "rmse", "edge_accuracy",
                                                      "flying_pixels", "missing", "invented")},
            }  # fmt: skip
            rows.append(row)
            print(json.dumps(row), flush=True)
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
