"""Samba benchmark (paper §7.3–7.4, Fig. 3 and 6): UP-SR against nearest and bicubic upsampling.

The Samba sequence (Vlasic et al. 2008, "Articulated mesh animation from multi-view
silhouettes"; triangle meshes in metres, Y up) is rendered with one fixed pinhole camera:

* the ground truth at high resolution (default 1024×588),
* the input at low resolution (1024×588 / r, e.g. 256×147 at r = 4) with the *same* field of
  view (``camera.scaled(1/r)``, ``SPEC.md`` §1 pixel geometry), point-sampled at the low-res
  pixel centres, then degraded by i.i.d. Laplacian noise of standard deviation σ mm on the
  valid pixels.

Each noisy low-res video is saved as ``lowres_sigma{σ}.npy`` and super-resolved by the command
line exactly as a user would run it (``upsr run lowres.npy -o upsr.npy --scale r --frames N``),
with and without deblurring; nearest and bicubic upsampling are the baselines. All methods are
scored with :func:`upsr.research.metrics.evaluate` on all frames (pooled). Renders are cached in
``--out`` so that reruns with the same geometry only redo the super-resolution.

Examples
--------
::

    .venv/bin/python benchmarks/samba_eval.py                       # r = 4, N = 9, σ = 0 10 30 50
    .venv/bin/python benchmarks/samba_eval.py --render-only --n-frames-total 30
    .venv/bin/python benchmarks/samba_eval.py --sigma 30 --upsr-args "--flow-preset fast"
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import shlex
import shutil
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from upsr.errors import InputError
from upsr.research import baselines
from upsr.research.experiments.data import render_samba
from upsr.research.metrics import evaluate
from upsr.research.synth.degradation import add_laplacian_noise
from upsr.research.synth.render import SAMBA_BOUNDS_M, SAMBA_VIEW_DIR, PinholeCamera, mesh_bounds

__all__ = ["main"]

REPO = Path(__file__).resolve().parents[1]
DEFAULT_DATA = REPO.parent / "shared" / "data"
METRICS = ("rmse", "mse", "surface_rmse", "edge_accuracy", "flying_pixels", "missing", "invented")
ALL_METHODS = ("nearest", "bicubic", "upsr_fused", "upsr")
#: Bump when the rendering code changes in a way that invalidates cached renders.
RENDER_VERSION = 2


# --------------------------------------------------------------------------------------------
# Building blocks
# --------------------------------------------------------------------------------------------


def upsr_command() -> list[str]:
    """How to call the installed command line (the venv's ``upsr`` script if present)."""
    exe = Path(sys.executable).with_name("upsr")
    if exe.is_file():
        return [str(exe)]
    found = shutil.which("upsr")
    if found:
        return [found]
    return [sys.executable, "-m", "upsr.apps.cli.main"]


def run_upsr_cli(
    lowres_path: Path, output_path: Path, r: int, n_frames: int, extra: Sequence[str]
) -> tuple[np.ndarray, float, str]:
    """Run ``upsr run`` as a user would; return (output video, wall time s, summary line)."""
    cmd = [
        *upsr_command(),
        "run",
        str(lowres_path),
        "-o",
        str(output_path),
        "--scale",
        str(r),
        "--frames",
        str(n_frames),
        "--overwrite",
        "-q",
        *extra,
    ]
    print("  $", shlex.join(cmd), flush=True)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    elapsed = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(
            f"upsr run failed (exit {proc.returncode}):\n{proc.stderr.strip() or proc.stdout}"
        )
    return np.load(output_path), elapsed, proc.stdout.strip()


# --------------------------------------------------------------------------------------------
# Rendering with a cache
# --------------------------------------------------------------------------------------------


def _sigma_tag(sigma: float) -> str:
    return f"{sigma:g}".replace("-", "m")


def render_cached(args: argparse.Namespace, out: Path) -> tuple[np.ndarray, np.ndarray, dict]:
    """Render (or load from ``out``) the high-res truth and the clean low-res video."""
    samba = Path(args.data) / "samba"
    paths = [
        samba / f"mesh_{k:04d}.obj" for k in range(args.start, args.start + args.n_frames_total)
    ]
    missing = [p for p in paths if not p.is_file()]
    if missing:
        raise InputError(f"missing Samba mesh {missing[0]} (--data, --start, --n-frames-total)")
    width, height = args.hr_size
    key = {
        "render_version": RENDER_VERSION,
        "meshes": [p.name for p in paths],
        "hr_size": [width, height],
        "scale": args.scale,
        "fov_x_deg": args.fov,
        "camera_fit": args.camera_fit,
        "wall_mm": args.wall_mm,
    }
    meta_path = out / "render_meta.json"
    truth_path, clean_path = out / "truth.npy", out / "lowres_clean.npy"
    if not args.force and meta_path.is_file() and truth_path.is_file() and clean_path.is_file():
        meta = json.loads(meta_path.read_text())
        if meta.get("key") == key:
            print(f"using cached renders in {out}")
            return np.load(truth_path), np.load(clean_path), meta

    bounds = None if args.camera_fit == "rendered" else SAMBA_BOUNDS_M
    print(
        f"rendering {len(paths)} meshes ({paths[0].name} …) at {width}×{height} and 1/{args.scale}"
    )
    t0 = time.perf_counter()
    rendered = render_samba(
        paths,
        width=width,
        height=height,
        scales=(1, args.scale),
        fov_x_deg=args.fov,
        background_mm=args.wall_mm,
        bounds_m=bounds,
    )
    total = time.perf_counter() - t0
    truth, clean = rendered.truth, rendered.lowres[args.scale]
    cam_hr, pose = rendered.camera, rendered.world_to_camera
    cam_lr = cam_hr.scaled(1 / args.scale)
    lo, hi = mesh_bounds(paths) if bounds is None else bounds
    bounds = (list(lo), list(hi))
    print(f"  {total:.2f} s (incl. JIT warm-up)")
    meta = {
        "key": key,
        "bounds_m": [list(map(float, b)) for b in bounds],
        "view_dir": list(SAMBA_VIEW_DIR),
        "camera_hr": _camera_dict(cam_hr),
        "camera_lr": _camera_dict(cam_lr),
        "world_to_camera": pose.tolist(),
        "render_seconds": {"total": total},
    }
    out.mkdir(parents=True, exist_ok=True)
    np.save(truth_path, truth)
    np.save(clean_path, clean)
    meta_path.write_text(json.dumps(meta, indent=2))
    for stale in out.glob("lowres_sigma*.npy"):  # noise was added to the old renders
        stale.unlink()
    return truth, clean, meta


def _camera_dict(cam: PinholeCamera) -> dict[str, float]:
    return {
        "fx": cam.fx,
        "fy": cam.fy,
        "cx": cam.cx,
        "cy": cam.cy,
        "width": cam.width,
        "height": cam.height,
    }


def noisy_lowres(clean: np.ndarray, sigma: float, seed: int, out: Path) -> Path:
    """Write (once) and return the path of the noisy low-res video for ``sigma``."""
    path = out / f"lowres_sigma{_sigma_tag(sigma)}.npy"
    seed_path = path.with_suffix(".seed")
    if path.is_file() and seed_path.is_file() and seed_path.read_text().strip() == str(seed):
        return path
    # One stream per (seed, σ): the noise for a σ does not depend on the other σ asked for.
    rng = np.random.default_rng([seed, round(sigma * 1000)])
    np.save(path, add_laplacian_noise(clean, sigma, rng).astype(np.float32))
    seed_path.write_text(str(seed))
    return path


# --------------------------------------------------------------------------------------------
# Report
# --------------------------------------------------------------------------------------------


def _fmt(value: Any, metric: str) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "nan"
    if metric in ("edge_accuracy", "flying_pixels", "missing", "invented"):
        return f"{100 * value:.2f}%"
    if metric == "mse":
        return f"{value:.1f}"
    if metric == "seconds":
        return f"{value:.1f}"
    return f"{value:.2f}"


def print_table(rows: list[dict[str, Any]]) -> None:
    cols = [*METRICS, "seconds"]
    header = ["sigma", "method", *cols]
    lines = [header]
    for row in rows:
        lines.append([f"{row['sigma']:g}", row["method"], *(_fmt(row.get(c), c) for c in cols)])
    widths = [max(len(line[i]) for line in lines) for i in range(len(header))]
    print()
    print("rmse/surface_rmse in mm, mse in mm², shares in % (edge_accuracy: higher is better)")
    for k, line in enumerate(lines):
        if k > 0 and line[0] != lines[k - 1][0] and k > 1:
            print()
        print(
            "  ".join(
                cell.rjust(w) if i > 1 else cell.ljust(w)
                for i, (cell, w) in enumerate(zip(line, widths, strict=True))
            )
        )


def write_results(rows: list[dict[str, Any]], config: dict[str, Any], out: Path) -> None:
    def clean(v: Any) -> Any:
        return None if isinstance(v, float) and math.isnan(v) else v

    payload = {"config": config, "results": [{k: clean(v) for k, v in r.items()} for r in rows]}
    (out / "results.json").write_text(json.dumps(payload, indent=2))
    fields = ["sigma", "method", *METRICS, "seconds"]
    extra = sorted({k for r in rows for k in r} - set(fields))
    with open(out / "results.csv", "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=fields + extra)
        writer.writeheader()
        for r in rows:
            writer.writerow({k: r.get(k, "") for k in fields + extra})


# --------------------------------------------------------------------------------------------
# Main
# --------------------------------------------------------------------------------------------


def _parse(argv: Sequence[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(
        description="Samba benchmark: render truth/low-res depth, run UP-SR and baselines, "
        "report the SPEC §6 metrics per noise level.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    p.add_argument(
        "--data", default=str(DEFAULT_DATA), help="shared data folder (holds samba/mesh_XXXX.obj)"
    )
    p.add_argument("--scale", "-r", type=int, default=4, help="SR factor r")
    p.add_argument("--frames", "-n", type=int, default=9, help="UP-SR window length N")
    p.add_argument("--start", type=int, default=0, help="first mesh index")
    p.add_argument(
        "--n-frames-total",
        type=int,
        default=15,
        help="number of consecutive meshes rendered (video length T)",
    )
    p.add_argument(
        "--sigma",
        type=float,
        nargs="+",
        default=[0.0, 10.0, 30.0, 50.0],
        help="Laplacian noise standard deviations (mm)",
    )
    p.add_argument("--seed", type=int, default=0, help="noise seed")
    p.add_argument("--out", default="results/samba_eval", help="output and cache folder")
    p.add_argument(
        "--hr-size",
        type=int,
        nargs=2,
        default=[1024, 588],
        metavar=("WIDTH", "HEIGHT"),
        help="high-res image size (px)",
    )
    p.add_argument("--fov", type=float, default=60.0, help="horizontal field of view (deg)")
    p.add_argument(
        "--camera-fit",
        choices=("rendered", "sequence"),
        default="rendered",
        help="frame the dancer's bounding box over the rendered meshes, or over "
        "the whole 175-frame sequence (one camera for every --start)",
    )
    p.add_argument(
        "--wall-mm",
        type=float,
        default=None,
        help="optional fronto-parallel back wall at this depth (mm); the paper's "
        "Samba scene has none (background 0)",
    )
    p.add_argument(
        "--methods",
        nargs="+",
        choices=ALL_METHODS,
        default=list(ALL_METHODS),
        help="methods to evaluate (upsr_fused: UP-SR with --no-deblur)",
    )
    p.add_argument(
        "--upsr-args", default="", help="extra options for 'upsr run', e.g. \"--flow-preset fast\""
    )
    p.add_argument(
        "--render-only",
        action="store_true",
        help="only render (and cache) truth and noisy inputs, then stop",
    )
    p.add_argument("--force", action="store_true", help="ignore cached renders")
    args = p.parse_args(argv)
    if args.scale < 1:
        p.error("--scale must be >= 1")
    if args.n_frames_total < 1 or args.start < 0:
        p.error("--n-frames-total must be >= 1 and --start >= 0")
    if not 1 <= args.frames <= args.n_frames_total:
        p.error("--frames must be in 1 .. --n-frames-total")
    if any(s < 0 or not math.isfinite(s) for s in args.sigma):
        p.error("--sigma values must be finite and >= 0")
    w, h = args.hr_size
    if w % args.scale or h % args.scale:
        p.error(f"--hr-size {w} {h} is not divisible by --scale {args.scale}")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = _parse(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    try:
        truth, clean, meta = render_cached(args, out)
    except InputError as exc:
        print(f"samba_eval: error: {exc}", file=sys.stderr)
        return 2
    r = args.scale
    valid = truth > 0
    print(
        f"truth {truth.shape}, {100 * valid.mean():.1f}% valid, depth "
        f"{truth[valid].min():.0f}–{truth[valid].max():.0f} mm; "
        f"low res {clean.shape}, {100 * (clean > 0).mean():.1f}% valid"
    )
    paths = {s: noisy_lowres(clean, s, args.seed, out) for s in args.sigma}
    if args.render_only:
        print("render only: wrote", ", ".join(p.name for p in [out / "truth.npy", *paths.values()]))
        return 0

    extra = shlex.split(args.upsr_args)
    rows: list[dict[str, Any]] = []
    for sigma in args.sigma:
        print(f"\nσ = {sigma:g} mm")
        lowres = np.load(paths[sigma])
        tag = _sigma_tag(sigma)
        for method in args.methods:
            t0 = time.perf_counter()
            summary = ""
            if method in ("nearest", "bicubic"):
                estimate = getattr(baselines, method)(lowres, r)
                seconds = time.perf_counter() - t0
            else:
                flags = ["--no-deblur"] if method == "upsr_fused" else []
                estimate, seconds, summary = run_upsr_cli(
                    paths[sigma], out / f"{method}_sigma{tag}.npy", r, args.frames, [*flags, *extra]
                )
            if estimate.shape != truth.shape:
                raise RuntimeError(
                    f"{method}: output shape {estimate.shape} != truth {truth.shape}"
                )
            scores = evaluate(estimate, truth, r)
            row: dict[str, Any] = {"sigma": sigma, "method": method, "seconds": seconds}
            row.update({k: float(v) for k, v in scores.items()})
            rows.append(row)
            print(
                f"  {method:10s} rmse {_fmt(row['rmse'], 'rmse')} mm, "
                f"edge acc {_fmt(row['edge_accuracy'], 'edge_accuracy')}, "
                f"flying {_fmt(row['flying_pixels'], 'flying_pixels')}  ({seconds:.1f} s)"
                + (f"  [{summary}]" if summary else ""),
                flush=True,
            )

    config = {k: v for k, v in vars(args).items() if k not in ("render_only", "force")}
    config.update(
        {k: meta[k] for k in ("camera_hr", "camera_lr", "world_to_camera", "bounds_m", "view_dir")}
    )
    config["upsr_command"] = upsr_command()
    config["evaluated_frames"] = "all (pooled)"
    print_table(rows)
    write_results(rows, config, out)
    print(f"\nwrote {out / 'results.json'} and {out / 'results.csv'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
