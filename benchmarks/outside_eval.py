"""Scenes built outside the rules' development (an audit of 7 Dec 2026): UP-SR against its peers.

Ten scenes that no rule of the method was tuned on, each rendered with the project's helpers
(:mod:`upsr.research.synth.realistic`'s static / moving camera renderers, the meshes of
:mod:`upsr.research.synth.primitives`, :mod:`upsr.geometry.rendering`) and seen through the
sensor models the audit's findings used (:func:`upsr.research.synth.realistic.degrade`):

* ``table`` — a static table with 1.2 px legs and a 1.6 px top, 2 m before a wall at 3 m; ToF
  footprint + Laplace 10 mm at 64×56 r = 4 and 80×60 r = 2, and with a ball rolling under it
  (9 frames); the ball variant also under Laplace 10 (15 frames: edges below nearest);
* ``kinect_wall`` — a bare static wall through the Kinect model (80×60, r = 2, 15 frames):
  slanted 35° at 4 and 5 m, fronto-parallel at 7 and 8 m, slanted 10° at 7 m;
* ``slanted`` — static camera, static scene: a wall yawed 50° at 2.5 m, a floor seen at a
  grazing angle, a tilted panel (64×56, r = 4, 15 frames; Laplace 0, 10, 30, Gauss 10);
* ``slanted_kinect`` — the same scene through the Kinect model at 160×120, r = 2;
* ``walker`` — a person of capsules (limbs 1–2 px) walking sideways 1.5 px/frame, 1 m before a
  wall; ToF + Laplace 10 at r = 4 and ToF + Gauss 10 at 80×60 r = 2 (15 frames);
* ``propeller`` — two 1.5 px blades spinning up (tip 1 → 12 px/frame) on a thin stand, 1 m
  before a wall; ToF + Laplace 10 at r = 4 (two noise draws) and Laplace 10 at 80×60 r = 2;
* ``toward_wall`` — the camera moving 25 mm/frame toward a wall yawed 25° at 1.5 m with a
  cylinder, a shelf and a ball on it (Laplace / Gauss 30; 15 frames);
* ``sphere`` — a ball (radius 0.25 m) coming 100 mm/frame nearer from 3 m while drifting
  (1.5, 1) px/frame, wall at 3.5 m (Laplace / Gauss 30 at r = 4, Laplace 10 at 80×60 r = 2);
* ``hand`` — a hand (palm, five 2 px fingers) waving 0.5 rad about the wrist at 55 cm before a
  wall at 1.4 m, Kinect model at 160×120 r = 2;
* ``corridor`` — a camera walking 40 mm/frame (3 mm shake) along a 14 m corridor with door
  posts, boxes and a bin: clean and Laplace 10 at r = 4, Kinect at 160×120 r = 2.

Sizes (w×h), r and clip lengths are the audit's: 64×56 at r = 4, 80×60 or 160×120 at r = 2,
15 frames (9 for the ToF table). Nothing was made smaller or shorter than in the audit: the
whole run (28 rows of 6 methods) takes under a minute on 2 busy cores, plus Numba's first
compilation when its cache is cold.

Methods, as ``realistic_eval.py``: ``upsr`` (``upsr.super_resolve(low, scale=r, n_frames=9)``,
defaults), ``upsr_recursive`` (the same with ``mode="recursive"``), ``nearest``, ``bicubic``,
``bilateral`` (:func:`upsr.research.peers.bilateral_nearest` told the true σ; per pixel for the
Kinect, as ``realistic_eval._sensor_sigma``) and ``temporal_mean`` (N = 9). The Kinect's input
is rounded to whole mm (a uint16 image, as the camera delivers it; upsr gets the uint16 array,
the peers the same values as float32). The noise of each row is drawn from a generator seeded
by ``--seed`` and the row's scene and sensor labels (the audit drew its own: the figures differ
by a noise draw).

Metrics: ``realistic_eval.score`` (SPEC §6 via :func:`upsr.research.metrics.evaluate`, the
surface RMSE on the moving and static parts, the mean signed error). Each upsr row lists the
done-when rules of issue #13 it fails: edge accuracy below nearest's; missing or invented more
than 0.5 points above nearest's; flying pixels ≥ 0.5 %; on noisy rows (σ ≥ 10 mm, ToF and
Kinect) rmse above nearest's or bicubic's and moving-surface rmse above the bilateral filter's;
with a static camera and Laplace / Gauss σ ≥ 10 a static-surface rmse above 0.2 σ; on the
camera toward the wall a mean bias of 1 mm or more; on the Kinect's static wall a surface rmse
above the temporal mean of the raw frames. Not ported from the audit: its per-pixel counts of
ghost finger depths on the hand's wall, of near-zero depths in the clean corridor, and its
surface-only bias of the approaching ball (their rows are here, with the metrics above), and
the camera-motion modes (the audit ran upsr with its defaults).

Example::

    .venv/bin/python benchmarks/outside_eval.py --out results/bench/outside
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
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

import upsr
from upsr.research import baselines, peers
from upsr.research.synth.realistic import (
    RealisticVideo,
    degrade,
)

sys.path.insert(0, str(Path(__file__).resolve().parent))
from outside_scenes import (
    corridor,
    hand,
    propeller,
    slanted,
    sphere_diag,
    static_wall,
    table_scene,
    toward_slanted_wall,
    walker,
)
from realistic_eval import COLUMNS as REALISTIC_COLUMNS
from realistic_eval import UPSR_METHODS, _fmt, _sensor_sigma, score, write_results

__all__ = ["SCENES", "failures", "main"]

Shape = tuple[int, int]

N_FRAMES = 9  # upsr's window N (the recursive mode's cap) and the temporal mean's window
#: realistic_eval's columns (the middle frame's bias aside: these clips' windows are whole)
COLUMNS = tuple(c for c in REALISTIC_COLUMNS if c != "bias_mid")
NOISY_SENSORS = ("tof", "tof_gaussian", "kinect")


# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Sensor:
    """One sensor row: its label, :func:`degrade`'s sensor and σ (mm)."""

    label: str
    kind: str
    sigma: float = 0.0


@dataclass(frozen=True)
class Case:
    """One rendered clip (``name`` labels its rows) and the sensors it is seen through."""

    name: str
    build: Callable[[], RealisticVideo]
    sensors: tuple[Sensor, ...]
    toward_wall: bool = False  # issue #13's rule on the mean bias applies
    kinect_wall: bool = False  # issue #13's rule against the temporal mean applies


TOF10 = Sensor("tof10", "tof", 10.0)
TOF10_B = Sensor("tof10_b", "tof", 10.0)  # a second noise draw
TOFG10 = Sensor("tofg10", "tof_gaussian", 10.0)
KINECT = Sensor("kinect", "kinect")
LAPLACE10 = Sensor("laplace10", "laplace", 10.0)
TOF_SIZE, KINECT_SIZE, MID_SIZE = (56, 64), (120, 160), (60, 80)  # (h, w)


def _kinect_walls() -> list[Case]:
    out = []
    for z, yaw in ((4000.0, 35.0), (5000.0, 35.0), (7000.0, 0.0), (8000.0, 0.0), (7000.0, 10.0)):
        name = f"kinect_wall_{z / 1000:g}m" + (f"_yaw{yaw:g}" if yaw else "")
        build = functools.partial(static_wall, MID_SIZE, 2, 15, z=z, yaw_deg=yaw)
        out.append(Case(name, build, (KINECT,), kinect_wall=True))
    return out


#: --scenes name -> its cases (shape (h, w), r and frame count as in the audit's scripts)
SCENES: dict[str, list[Case]] = {
    "table": [  # f01 (ToF, 9 frames) and f11 (Laplace, 15 frames)
        Case("table", lambda: table_scene(TOF_SIZE, 4, 9, ball=False), (TOF10,)),
        Case("table_r2", lambda: table_scene(MID_SIZE, 2, 9, ball=False), (TOF10,)),
        Case("table_ball", lambda: table_scene(TOF_SIZE, 4, 9, ball=True), (TOF10,)),
        Case("table_ball_15", lambda: table_scene(TOF_SIZE, 4, 15, ball=True), (LAPLACE10,)),
    ],
    "kinect_wall": _kinect_walls(),  # f02
    "slanted": [  # f03
        Case(
            "slanted",
            lambda: slanted(TOF_SIZE, 4, 15),
            (
                Sensor("laplace0", "laplace", 0.0),
                LAPLACE10,
                Sensor("gauss10", "gaussian", 10.0),
                Sensor("laplace30", "laplace", 30.0),
            ),
        )
    ],
    "slanted_kinect": [Case("slanted_kinect", lambda: slanted(KINECT_SIZE, 2, 15), (KINECT,))],
    "walker": [  # f05
        Case("walker", lambda: walker(TOF_SIZE, 4, 15), (TOF10,)),
        Case("walker_r2", lambda: walker(MID_SIZE, 2, 15), (TOFG10,)),
    ],
    "propeller": [  # f06 (two noise draws) and f11
        Case("propeller", lambda: propeller(TOF_SIZE, 4, 15), (TOF10, TOF10_B)),
        Case("propeller_r2", lambda: propeller(MID_SIZE, 2, 15), (LAPLACE10,)),
    ],
    "toward_wall": [  # f07
        Case(
            "toward_slanted_wall",
            lambda: toward_slanted_wall(TOF_SIZE, 4, 15),
            (Sensor("laplace30", "laplace", 30.0), Sensor("gauss30", "gaussian", 30.0)),
            toward_wall=True,
        )
    ],
    "sphere": [  # f08
        Case(
            "sphere_diag",
            lambda: sphere_diag(TOF_SIZE, 4, 15),
            (Sensor("laplace30", "laplace", 30.0), Sensor("gauss30", "gaussian", 30.0)),
        ),
        Case("sphere_diag_r2", lambda: sphere_diag(MID_SIZE, 2, 15), (LAPLACE10,)),
    ],
    "hand": [Case("hand_kinect", lambda: hand(KINECT_SIZE, 2, 15), (KINECT,))],  # f09
    "corridor": [  # f10
        Case("corridor", lambda: corridor(TOF_SIZE, 4, 15), (Sensor("clean", "clean"), LAPLACE10)),
        Case("corridor_kinect", lambda: corridor(KINECT_SIZE, 2, 15), (KINECT,)),
    ],
}


# --------------------------------------------------------------------------------------------
# Running and scoring
# --------------------------------------------------------------------------------------------


def sensor_input(video: RealisticVideo, case: str, sensor: Sensor, seed: int) -> np.ndarray:
    """The row's low-res input: ``degrade`` with a generator seeded by ``seed`` and the row's
    labels (each row its own noise); the Kinect's rounded to whole mm (float32)."""
    rng = np.random.default_rng([seed, zlib.crc32(f"{case}/{sensor.label}".encode())])
    low = degrade(video, sensor.kind, rng, sigma_mm=sensor.sigma)
    return np.round(low) if sensor.kind == "kinect" else low


def _methods(r: int, sensor: Sensor) -> dict[str, Callable[[np.ndarray], np.ndarray]]:
    def upsr_input(low: np.ndarray) -> np.ndarray:
        return low.astype(np.uint16) if sensor.kind == "kinect" else low

    return {
        "upsr": lambda low: upsr.super_resolve(upsr_input(low), scale=r, n_frames=N_FRAMES),
        "upsr_recursive": lambda low: upsr.super_resolve(
            upsr_input(low), scale=r, n_frames=N_FRAMES, mode="recursive"
        ),
        "nearest": lambda low: baselines.nearest(low, r),
        "bicubic": lambda low: baselines.bicubic(low, r),
        "bilateral": lambda low: peers.bilateral_nearest(
            low, r, _sensor_sigma(sensor.kind, low, sensor.sigma)
        ),
        "temporal_mean": lambda low: peers.temporal_mean(low, r, min(N_FRAMES, low.shape[0])),
    }


def _ok(v: Any) -> bool:
    return v is not None and not (isinstance(v, float) and math.isnan(v))


def _pct(v: float) -> str:
    return f"{100 * v:.2f}"


def failures(
    up: dict[str, Any],
    peer: dict[str, dict[str, Any]],
    sensor: Sensor,
    *,
    static_camera: bool,
    toward_wall: bool = False,
    kinect_wall: bool = False,
) -> list[str]:
    """Issue #13's done-when rules that the upsr row ``up`` fails against its ``peer`` rows
    (``nearest``, ``bicubic``, ``bilateral``, ``temporal_mean``), each as a short text."""
    near, bic, bil, tm = (peer[k] for k in ("nearest", "bicubic", "bilateral", "temporal_mean"))
    out = []
    if _ok(near["edge_accuracy"]) and up["edge_accuracy"] < near["edge_accuracy"]:
        out.append(f"edge {_pct(up['edge_accuracy'])} < nearest {_pct(near['edge_accuracy'])}")
    for k in ("missing", "invented"):
        if _ok(near[k]) and _ok(up[k]) and up[k] > near[k] + 0.005:
            out.append(f"{k} {_pct(up[k])} > nearest {_pct(near[k])} + 0.5")
    if _ok(up["flying_pixels"]) and up["flying_pixels"] >= 0.005:
        out.append(f"flying {_pct(up['flying_pixels'])} ≥ 0.5")
    noisy = sensor.kind in NOISY_SENSORS or sensor.sigma >= 10
    if noisy:
        for name, row in (("nearest", near), ("bicubic", bic)):
            if up["rmse"] > row["rmse"]:
                out.append(f"rmse {up['rmse']:.2f} > {name} {row['rmse']:.2f}")
        a, b = up["surface_moving"], bil["surface_moving"]
        if _ok(a) and _ok(b) and a > b:
            out.append(f"surface_moving {a:.2f} > bilateral {b:.2f}")
    if static_camera and sensor.kind in ("laplace", "gaussian") and sensor.sigma >= 10:
        a = up["surface_static"]
        if _ok(a) and a > 0.2 * sensor.sigma:
            out.append(f"surface_static {a:.2f} > 0.2σ = {0.2 * sensor.sigma:g}")
    if toward_wall and _ok(up["bias"]) and abs(up["bias"]) >= 1.0:
        out.append(
            f"bias {up['bias']:+.2f} mm, 1 or more in size (surfaces {up['bias_surface']:+.2f})"
        )
    if kinect_wall and up["surface_rmse"] > tm["surface_rmse"]:
        out.append(f"surface {up['surface_rmse']:.2f} > temporal mean {tm['surface_rmse']:.2f}")
    return out


def run_case(case: Case, seed: int, t_start: float) -> list[dict[str, Any]]:
    """Every (sensor, method) row of one clip, upsr's rows with their failed rules."""
    video = case.build()
    r = video.scale
    rows = []
    for sensor in case.sensors:
        low = sensor_input(video, case.name, sensor, seed)
        by_method = {}
        for method, fn in _methods(r, sensor).items():
            t0 = time.perf_counter()
            est = fn(low)
            secs = time.perf_counter() - t0
            by_method[method] = {
                "scene": case.name,
                "sensor": sensor.label,
                "method": method,
                "input": f"{low.shape[2]}×{low.shape[1]} r={r} T={low.shape[0]}",
                **score(est, video),
                "seconds": secs,
            }
        for method in UPSR_METHODS:
            by_method[method]["fails"] = failures(
                by_method[method],
                by_method,
                sensor,
                static_camera=video.static_camera,
                toward_wall=case.toward_wall,
                kinect_wall=case.kinect_wall,
            )
        rows += by_method.values()
        n_fail = [len(by_method[m]["fails"]) for m in UPSR_METHODS]
        print(
            f"{case.name:22s} {sensor.label:10s} done ({time.perf_counter() - t_start:.0f} s); "
            f"rules failed: upsr {n_fail[0]}, recursive {n_fail[1]}",
            flush=True,
        )
    return rows


# --------------------------------------------------------------------------------------------
# Output
# --------------------------------------------------------------------------------------------


def markdown(rows: list[dict[str, Any]], config: dict[str, Any]) -> str:
    """The results as Markdown: the rules upsr fails, the approaching camera's per-frame bias,
    then every row."""
    lines = [
        "# Scenes built outside the rules' development (audit of 7 Dec 2026)",
        "",
        f"`benchmarks/outside_eval.py {config['argv']}` at {config['commit']} (seed "
        f"{config['seed']}, window N = {N_FRAMES}, "
        f"{config['total_seconds']:.0f} s). Depths and errors in mm, shares in %. "
        "surface_moving / surface_static: surface RMSE (pixels > r px from a depth edge) on "
        "the moving parts of the truth (every pixel when the camera moves) / on the static "
        "ones; bias: mean(output − truth) over all frames; bias_surface: the same on the "
        "surface pixels.",
        "",
        "## Issue #13's done-when rules that upsr fails",
        "",
        "| scene | sensor | input (w×h) | upsr (windowed) | upsr recursive |",
        "|---|---|---|---|---|",
    ]
    by = {(r["scene"], r["sensor"], r["method"]): r for r in rows}
    for scene, sensor in dict.fromkeys((r["scene"], r["sensor"]) for r in rows):
        cells = ["; ".join(by[(scene, sensor, m)]["fails"]) or "—" for m in UPSR_METHODS]
        inp = by[(scene, sensor, "upsr")]["input"]
        lines.append(f"| {scene} | {sensor} | {inp} | {cells[0]} | {cells[1]} |")
    toward = [
        r
        for r in rows
        if r["scene"] == "toward_slanted_wall" and r["method"] in (*UPSR_METHODS, "nearest")
    ]
    if toward:
        n = len(toward[0]["bias_per_frame"])
        lines += [
            "",
            "## Per-frame bias, camera toward the slanted wall (mean(output − truth), mm)",
            "",
            "| sensor | method | " + " | ".join(f"t={t}" for t in range(n)) + " |",
            "|---|---|" + "---:|" * n,
        ]
        for r in toward:
            cells = " | ".join(_fmt(b, "bias") for b in r["bias_per_frame"])
            lines.append(f"| {r['sensor']} | {r['method']} | {cells} |")
    lines += ["", "## All results", ""]
    lines.append("| scene | sensor | method | " + " | ".join(COLUMNS) + " | rules failed |")
    lines.append("|---|---|---|" + "---:|" * len(COLUMNS) + "---|")
    for r in rows:
        cells = [_fmt(r.get(c), c) for c in COLUMNS]
        fails = ("; ".join(r["fails"]) or "—") if "fails" in r else ""
        lines.append(
            f"| {r['scene']} | {r['sensor']} | {r['method']} | " + " | ".join(cells)
            + f" | {fails} |"
        )  # fmt: skip
    return "\n".join(lines) + "\n"


def _parse(argv: Sequence[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="results/bench/outside", help="output folder")
    p.add_argument(
        "--scenes", nargs="+", default=list(SCENES), choices=list(SCENES), help="default: all"
    )
    p.add_argument("--seed", type=int, default=0, help="seeds the sensors' noise")
    return p.parse_args(argv)


def _commit() -> str:
    """The checkout's commit (short), or "?" outside a git checkout."""
    import subprocess

    done = subprocess.run(
        ["git", "-C", str(Path(__file__).resolve().parent), "rev-parse", "--short", "HEAD"],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    return done.stdout.strip() or "?"


def write_report(out: Path, res: dict[str, Any], text: str, started: float) -> None:
    """``res`` as ``out``/results.json and ``text`` as results.md; print both's end (a
    benchmark started at ``started``, ``time.perf_counter()``)."""
    out.mkdir(parents=True, exist_ok=True)
    (out / "results.json").write_text(json.dumps(res, indent=1, default=float))
    (out / "results.md").write_text(text)
    print(text)
    print(f"total {time.perf_counter() - started:.0f} s; wrote {out}/results.json and results.md")


def main(argv: Sequence[str] | None = None) -> int:
    args = _parse(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    config: dict[str, Any] = {
        "argv": " ".join(sys.argv[1:] if argv is None else argv),
        "commit": _commit(),
        "scenes": args.scenes,
        "seed": args.seed,
        "n": N_FRAMES,
    }
    rows: list[dict[str, Any]] = []
    t_start = time.perf_counter()
    for scene in args.scenes:
        for case in SCENES[scene]:
            rows += run_case(case, args.seed, t_start)
    config["total_seconds"] = time.perf_counter() - t_start
    write_results(out, config, rows, markdown(rows, config))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
