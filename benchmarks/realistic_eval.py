"""Realistic-sensor benchmark: UP-SR against simple peers on scenes and sensors of real cameras.

Scenes (:mod:`upsr.research.synth.realistic`): a galloping animal with 1–2 px legs and antlers
in front of a wall (``gallop``) or of nothing (``gallop_none``), a camera moving 25 mm per
frame towards a wall with boxes (``toward_wall``), a deforming body whose head moves ≈ 25 px
per frame (``deforming``) and a room seen by a moving camera (``room``, every pixel measured).

Sensors (:func:`upsr.research.synth.realistic.degrade`): i.i.d. Laplacian noise of std σ
(``--sigma``, default 0, 10, 30 mm), Gaussian noise (``--gaussian-sigma``, 20 mm), a ToF
footprint (block mean of the truth: mixed pixels at edges, no return where the block is mostly
empty; plus Laplacian ``--tof-sigma`` = 10 mm and ``--tof-dropout`` = 0 of the pixels lost) at
the ToF size (56×64, r = 4; another with ``--tof-shape``), and a Kinect v1 (shadows, Nguyen et
al. 2012 noise, 1/8 px disparity, 1 % dropouts) at the Kinect size (120×160, r = 2; 240×320
with ``--full-kinect``).

Methods: ``upsr`` (``upsr.super_resolve(frames, scale=r, n_frames=N)``, defaults),
``upsr_recursive`` (the same with ``mode="recursive"``: causal, N caps the state),
``upsr_camera_motion`` and ``upsr_recursive_camera_motion`` on the scenes seen by a moving
camera (both modes with ``camera_motion="depth"`` and the scene's intrinsics:
:mod:`upsr.method.camera_motion`), its input
``nearest``, ``bicubic``, ``bilateral`` (per-frame masked bilateral on the nearest upsampling,
told the true σ: :func:`upsr.research.peers.bilateral_nearest`), ``temporal_mean`` (mean of
the raw frames of the window: fair only on static parts seen by a static camera) and
``straightforward`` (:func:`upsr.research.oracle.super_resolve_straightforward`, the slow
reference implementation: in ``--quick`` for the σ = 10 mm Laplacian sensor only, otherwise on
the first N frames of each clip).

Metrics: SPEC §6 (:func:`upsr.research.metrics.evaluate`, pooled over the frames) plus the
surface RMSE (pixels > r px from a depth discontinuity) on the moving parts of the truth and on
the static parts separately, and the mean signed error (output − truth, mm) on the pixels valid
in both (all frames, the middle frame, and per frame in results.json). The summary lists, per
case, the metrics on which UP-SR is worse than its input (nearest upsampling).

Example::

    .venv/bin/python benchmarks/realistic_eval.py --quick --out docs/results/realistic
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import sys
import time
import zlib
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

import upsr
from upsr.errors import InputError
from upsr.research import baselines, peers
from upsr.research.metrics import evaluate, near_discontinuity
from upsr.research.synth import degradation as deg
from upsr.research.synth.realistic import RealisticVideo, degrade, make_realistic

__all__ = ["main", "scene_options", "score", "sensor_frames", "write_results"]

ALL_SCENES = ("gallop", "gallop_none", "toward_wall", "deforming", "room", "fan")
#: Left out of --quick unless asked for: the animal without a wall, and the out-of-sample scene.
NOT_QUICK = ("gallop_none", "fan")
COLUMNS = (
    "rmse",
    "surface_rmse",
    "surface_moving",
    "surface_static",
    "edge_accuracy",
    "flying_pixels",
    "missing",
    "invented",
    "bias",
    "bias_surface",
    "bias_mid",
    "seconds",
)
#: metric -> True when higher is better (for the "worse than nearest" summary)
HIGHER_BETTER = {
    "rmse": False,
    "surface_rmse": False,
    "surface_moving": False,
    "surface_static": False,
    "edge_accuracy": True,
    "flying_pixels": False,
    "missing": False,
    "invented": False,
}


def score(estimate: np.ndarray, video: RealisticVideo, frames: slice = slice(None)) -> dict:
    """SPEC §6 metrics plus moving / static surface RMSE and the mean signed error."""
    truth, moving = video.truth[frames], video.moving[frames]
    est = np.asarray(estimate, np.float32)
    m = evaluate(est, truth, video.scale)
    both = (est > 0) & (truth > 0)
    surface = both & ~near_discontinuity(truth, video.scale)
    err = est.astype(np.float64) - truth

    def rms(mask: np.ndarray) -> float:
        return math.sqrt(float(np.mean(err[mask] ** 2))) if mask.any() else math.nan

    m["surface_moving"] = rms(surface & moving)
    m["surface_static"] = rms(surface & ~moving)
    m["bias"] = float(err[both].mean()) if both.any() else math.nan
    # (the edge band's wrong-side pixels are a metre off: the bias of the radial motion's
    # compensation is the surfaces')
    m["bias_surface"] = float(err[surface].mean()) if surface.any() else math.nan
    per_frame = [
        float(e[b].mean()) if b.any() else math.nan for e, b in zip(err, both, strict=True)
    ]
    m["bias_per_frame"] = per_frame
    m["bias_mid"] = per_frame[len(per_frame) // 2]
    return m


def _sensor_sigma(sensor: str, low: np.ndarray, sigma: float) -> float | np.ndarray:
    """The noise std (mm) the bilateral peer is told, per low-res pixel for the Kinect."""
    if sensor != "kinect":
        return sigma
    z = np.where(low > 0, low, 1000.0).astype(np.float64)
    step = z**2 * deg.KINECT_DISPARITY_STEP_PX / (deg.KINECT_FOCAL_PX * deg.KINECT_BASELINE_MM)
    return np.hypot(deg.kinect_axial_sigma_mm(z), step / math.sqrt(12.0)).astype(np.float32)


def _methods(
    r: int, n: int, sensor: str, sigma: float, with_oracle: bool
) -> dict[str, Callable[[np.ndarray], np.ndarray]]:
    from upsr.method.config import UPSRConfig
    from upsr.research.oracle import super_resolve_straightforward

    out: dict[str, Callable[[np.ndarray], np.ndarray]] = {
        "upsr": lambda low: upsr.super_resolve(low, scale=r, n_frames=n),
        "upsr_recursive": lambda low: upsr.super_resolve(
            low, scale=r, n_frames=n, mode="recursive"
        ),
        "nearest": lambda low: baselines.nearest(low, r),
        "bicubic": lambda low: baselines.bicubic(low, r),
        "bilateral": lambda low: peers.bilateral_nearest(low, r, _sensor_sigma(sensor, low, sigma)),
        "temporal_mean": lambda low: peers.temporal_mean(low, r, n),
    }
    if with_oracle:
        out["straightforward"] = lambda low: super_resolve_straightforward(
            low, UPSRConfig.from_options(r, n)
        )
    return out


def _sensors(args: argparse.Namespace) -> list[tuple[str, str, float]]:
    """(label, sensor, σ) of every sensor model."""
    out = [(f"laplace{s:g}", "laplace", s) for s in args.sigma]
    out.append((f"gauss{args.gaussian_sigma:g}", "gaussian", args.gaussian_sigma))
    drop = f"drop{100 * args.tof_dropout:g}" if args.tof_dropout else ""
    law = "g" if args.tof_law == "gaussian" else ""
    sensor = "tof_gaussian" if law else "tof"
    out.append((f"tof{law}{args.tof_sigma:g}{drop}", sensor, args.tof_sigma))
    out.append(("kinect", "kinect", 0.0))
    return out


def sensor_frames(
    video: RealisticVideo,
    label: str,
    sensor: str,
    sigma: float,
    seed: int,
    dropout_fraction: float = 0.0,
) -> np.ndarray:
    """The low-res input of the row ``label`` (e.g. "gauss20") of a scene: ``degrade`` with a
    generator seeded by ``seed`` and the scene's and row's names (each row its own noise)."""
    rng = np.random.default_rng([seed, zlib.crc32(f"{video.name}/{label}".encode())])
    return degrade(video, sensor, rng, sigma_mm=sigma, dropout_fraction=dropout_fraction)


def _run_case(
    video: RealisticVideo, label: str, sensor: str, sigma: float, args: argparse.Namespace
) -> list[dict[str, Any]]:
    drop = args.tof_dropout if sensor.startswith("tof") else 0.0
    low = sensor_frames(video, label, sensor, sigma, args.seed, drop)
    n = min(args.n, video.n_frames)
    oracle = (not args.quick and args.oracle) or (args.quick and label == "laplace10")
    rows = []
    methods = _methods(video.scale, n, sensor, sigma, oracle)
    if video.world_to_camera is not None:  # a moving camera: its own motion from the depth
        c = video.camera
        for name, mode in (("upsr_camera_motion", "windowed"),
                           ("upsr_recursive_camera_motion", "recursive")):  # fmt: skip
            methods[name] = functools.partial(
                upsr.super_resolve, scale=video.scale, n_frames=n, mode=mode,
                camera_motion="depth", camera_intrinsics=(c.fx, c.fy, c.cx, c.cy),
            )  # fmt: skip
    for method, fn in methods.items():
        frames = slice(None)
        clip = low
        if method == "straightforward" and not args.quick:
            frames, clip = slice(0, n), low[:n]
        t0 = time.perf_counter()
        est = fn(clip)
        secs = time.perf_counter() - t0
        row = {"scene": video.name, "sensor": label, "method": method, **score(est, video, frames)}
        row["seconds"] = secs
        rows.append(row)
    return rows


def _fmt(v: Any, col: str) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "–"
    if col in ("edge_accuracy", "flying_pixels", "missing", "invented"):
        return f"{100 * v:.1f}"
    if col == "seconds":
        return f"{v:.2f}"
    return f"{v:.1f}"


#: The modes of upsr whose losses against nearest are summarised.
UPSR_METHODS = ("upsr", "upsr_recursive")


def _losses(rows: list[dict[str, Any]]) -> dict[tuple[str, str, str], list[str]]:
    """Per (scene, sensor, upsr mode): the metrics on which it is worse than nearest (its
    input)."""
    by = {(r["scene"], r["sensor"], r["method"]): r for r in rows}
    out = {}
    for scene, sensor, method in by:
        if method not in UPSR_METHODS:
            continue
        up, near = by[(scene, sensor, method)], by[(scene, sensor, "nearest")]
        worse = []
        for k, higher in HIGHER_BETTER.items():
            a, b = up.get(k), near.get(k)
            if a is None or b is None or math.isnan(a) or math.isnan(b):
                continue
            tol = 0.005 if k in ("edge_accuracy", "flying_pixels", "missing", "invented") else 0.5
            if (a < b - tol) if higher else (a > b + tol):
                worse.append(f"{k} {_fmt(a, k)} vs {_fmt(b, k)}")
        out[(scene, sensor, method)] = worse
    return out


def markdown(rows: list[dict[str, Any]], config: dict[str, Any]) -> str:
    """The results as Markdown: the summary of upsr's losses, then every row."""
    lines = [
        "# Realistic sensors: UP-SR against simple peers",
        "",
        f"`benchmarks/realistic_eval.py {config['argv']}`",
        "",
        "Scenes ToF size "
        f"{config['tof_shape'][1]}×{config['tof_shape'][0]} r = {config['tof_scale']}, Kinect size "
        f"{config['kinect_shape'][1]}×{config['kinect_shape'][0]} r = {config['kinect_scale']}; "
        f"{config['frames']} frames, window N = {config['n']}. Depths and errors in mm, shares "
        "in %. surface_moving / surface_static: surface RMSE on the moving parts of the truth "
        "(all pixels when the camera moves) / on the static ones. bias: mean(output − truth) "
        "over all frames; bias_surface: the same on the surface pixels (> r px from a depth "
        "edge); bias_mid: on the middle frame only, the one whose window is centred "
        "(near the ends of a clip the windows are shifted inwards; with T = N every other "
        "frame's window is off-centre).",
        "",
        "## Where upsr is worse than its input (nearest)",
        "",
        "| scene | sensor | upsr (windowed) worse than nearest on | upsr recursive |",
        "|---|---|---|---|",
    ]
    losses = _losses(rows)
    for scene, sensor in dict.fromkeys((k[0], k[1]) for k in losses):
        cells = [
            "; ".join(losses[(scene, sensor, m)]) or "—" if (scene, sensor, m) in losses else ""
            for m in UPSR_METHODS
        ]
        lines.append(f"| {scene} | {sensor} | {cells[0]} | {cells[1]} |")
    moving_cam = [r for r in rows if r["scene"] == "toward_wall" and r["method"] == "upsr"]
    if moving_cam:
        lines += [
            "",
            "## Per-frame bias, camera toward the wall (upsr, mean(output − truth) in mm)",
            "",
            "| sensor | "
            + " | ".join(f"t={t}" for t in range(len(moving_cam[0]["bias_per_frame"])))
            + " |",
            "|---|" + "---:|" * len(moving_cam[0]["bias_per_frame"]),
        ]
        for r in moving_cam:
            cells = " | ".join(_fmt(b, "bias") for b in r["bias_per_frame"])
            lines.append(f"| {r['sensor']} | {cells} |")
    lines += ["", "## All results", ""]
    lines.append("| scene | sensor | method | " + " | ".join(COLUMNS) + " |")
    lines.append("|---|---|---|" + "---:|" * len(COLUMNS))
    for r in rows:
        cells = [_fmt(r.get(c), c) for c in COLUMNS]
        lines.append(
            f"| {r['scene']} | {r['sensor']} | {r['method']} | " + " | ".join(cells) + " |"
        )
    return "\n".join(lines) + "\n"


def scene_options(items: Sequence[str]) -> dict[str, float]:
    """``--scene-option NAME=VALUE`` items as keywords of a scene function (numbers; whole
    numbers as int)."""
    out: dict[str, float] = {}
    for item in items:
        name, sep, value = item.partition("=")
        try:
            number = float(value)
        except ValueError:
            sep = ""
        if not sep or not name.strip():
            raise ValueError(f"--scene-option wants NAME=NUMBER, got {item!r}")
        out[name.strip()] = int(value) if value.strip().isdigit() else number
    return out


def _parse(argv: Sequence[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="docs/results/realistic", help="output folder")
    p.add_argument("--quick", action="store_true", help="small fast version (< 2 min)")
    p.add_argument(
        "--scenes",
        nargs="+",
        default=None,
        choices=ALL_SCENES,
        help="default: all; --quick: all but gallop_none and fan (the out-of-sample scene)",
    )
    p.add_argument("--sigma", type=float, nargs="+", default=[0.0, 10.0, 30.0], help="Laplace σ")
    p.add_argument("--gaussian-sigma", type=float, default=20.0)
    p.add_argument("--tof-sigma", type=float, default=10.0)
    p.add_argument(
        "--tof-dropout",
        type=float,
        default=0.0,
        help="share of the ToF pixels that return nothing (e.g. 0.01; issue #13's case: "
        "--tof-sigma 20 --tof-dropout 0.01)",
    )
    p.add_argument(
        "--tof-law",
        choices=("laplace", "gaussian"),
        default="laplace",
        help="noise of the ToF sensor (gaussian: rows labelled tofg…)",
    )
    p.add_argument("--frames", "-t", type=int, default=None, help="frames per clip")
    p.add_argument("--n", type=int, default=9, help="UP-SR window length N")
    p.add_argument("--full-kinect", action="store_true", help="Kinect scenes at 240×320")
    p.add_argument(
        "--tof-shape",
        type=int,
        nargs=2,
        default=(56, 64),
        metavar=("H", "W"),
        help="ToF sensor size (low-res px, r = 4); default 56 64",
    )
    p.add_argument(
        "--scene-option",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="a keyword of the scene function, a number (e.g. speed_mm=50 wall_depth_mm=4000 "
        "for toward_wall; see upsr.research.synth.realistic); repeatable, given to every scene",
    )
    p.add_argument("--no-oracle", dest="oracle", action="store_false")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    try:
        args.scene_kwargs = scene_options(args.scene_option)
    except ValueError as exc:
        p.error(str(exc))
    if args.frames is None:
        args.frames = 9 if args.quick else 15
    if args.scenes is None:
        args.scenes = [s for s in ALL_SCENES if not (args.quick and s in NOT_QUICK)]
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = _parse(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    tof_shape, tof_r = tuple(args.tof_shape), 4
    kin_shape, kin_r = ((240, 320), 2) if args.full_kinect else ((120, 160), 2)
    config = {
        "argv": " ".join(sys.argv[1:] if argv is None else argv),
        "tof_shape": tof_shape,
        "tof_scale": tof_r,
        "kinect_shape": kin_shape,
        "kinect_scale": kin_r,
        "frames": args.frames,
        "n": args.n,
        "seed": args.seed,
        "quick": args.quick,
        "scene_options": args.scene_kwargs,
    }
    rows: list[dict[str, Any]] = []
    t_start = time.perf_counter()
    for scene in args.scenes:
        videos = {}
        for label, sensor, sigma in _sensors(args):
            shape, r = (kin_shape, kin_r) if sensor == "kinect" else (tof_shape, tof_r)
            if shape not in videos:
                try:
                    videos[shape] = make_realistic(
                        scene, shape, scale=r, n_frames=args.frames, seed=args.seed,
                        **args.scene_kwargs,
                    )  # fmt: skip
                except (TypeError, InputError) as exc:  # a --scene-option the scene lacks
                    raise SystemExit(f"realistic_eval.py: scene {scene!r}: {exc}") from None
            rows += _run_case(videos[shape], label, sensor, sigma, args)
            print(
                f"{scene:12s} {label:10s} done ({time.perf_counter() - t_start:.0f} s)", flush=True
            )
    config["total_seconds"] = time.perf_counter() - t_start
    write_results(out, config, rows, markdown(rows, config))
    return 0


def write_results(out: Path, config: dict[str, Any], rows: list[dict[str, Any]], text: str) -> None:
    """``out/results.json`` (the config and the rows, NaN as null, in lists too) and
    ``out/results.md`` (``text``, also printed)."""

    def clean(v: Any) -> Any:
        return None if isinstance(v, float) and math.isnan(v) else v

    payload = {
        "config": config,
        "results": [
            {k: [clean(x) for x in v] if isinstance(v, list) else clean(v) for k, v in r.items()}
            for r in rows
        ],
    }
    (out / "results.json").write_text(json.dumps(payload, indent=2))
    (out / "results.md").write_text(text)
    print(text)
    print(f"total {config['total_seconds']:.0f} s; wrote {out / 'results.json'} and results.md")


if __name__ == "__main__":
    raise SystemExit(main())
