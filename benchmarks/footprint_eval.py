"""Whether a video's sensor mixes depths at edges (``remove_mixed="auto"``), measured.

A footprint sensor (ToF) mixes the depths of the surfaces its pixel straddles; a point
sampler (structured light, stereo, renders) does not. UP-SR removes mixed pixels only on a
sensor that mixes (:mod:`upsr.method.footprint`, :func:`upsr.method.statistics.sensor_mixes`):
the windowed engine decides from its first N frames, the recursive engine from its frames so
far (pooled as they arrive, over its first N). This benchmark runs both decisions on videos
whose sensor is known and counts the wrong ones:

* the windowed decision: :func:`upsr.method.statistics.pinned_config` of the first N = 9
  frames (what the engine fixes with its N-th frame);
* the recursive decision after each of its first 9 frames
  (``upsr.UPSR(mode="recursive").statistics.remove_mixed`` after each ``push``).

Videos: the realistic scenes (``gallop``, ``toward_wall``, ``deforming``, ``room`` of
:mod:`upsr.research.synth.realistic`) at 64×56, r = 4, seeds 0–7 and at 128×112 seeds 0–3
(the Kinect at 160×120 / 320×240, r = 2; ``--quick``: 64×56, seeds 0–1), each through
Laplace σ = 0 / 10 / 30 mm, Gauss 20, ToF footprint + Laplace 10, ToF 20 + 1 % dropouts,
ToF 30 and the Kinect model (rounded to whole mm); and every scene and sensor of
``outside_eval.py`` (thin table legs, propeller blades, a walker, walls, a corridor, ...)
with noise seeds 0–2. The truth: the ToF sensors mix, the others do not.

Example::

    .venv/bin/python benchmarks/footprint_eval.py --out docs/results/footprint
"""

from __future__ import annotations

import argparse
import sys
import time
import zlib
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

import upsr
from upsr.method.config import UPSRConfig
from upsr.method.statistics import pinned_config
from upsr.research.synth.realistic import degrade, make_realistic

sys.path.insert(0, str(Path(__file__).resolve().parent))

__all__ = ["main"]

N_FRAMES = 9
SCENES = ("gallop", "toward_wall", "deforming", "room")
#: (label, degrade's sensor, σ mm, dropout share)
SENSORS = (
    ("laplace0", "laplace", 0.0, 0.0),
    ("laplace10", "laplace", 10.0, 0.0),
    ("laplace30", "laplace", 30.0, 0.0),
    ("gauss20", "gaussian", 20.0, 0.0),
    ("tof10", "tof", 10.0, 0.0),
    ("tof20drop1", "tof", 20.0, 0.01),
    ("tof30", "tof", 30.0, 0.0),
    ("kinect", "kinect", 0.0, 0.0),
)
#: (ToF / point-sampler size (h, w), Kinect size, seeds)
SIZES = (((56, 64), (120, 160), range(8)), ((112, 128), (240, 320), range(4)))
QUICK_SIZES = (((56, 64), (120, 160), range(2)),)


def realistic_videos(quick: bool) -> Iterator[tuple[str, np.ndarray, int, bool]]:
    """(label, low-res frames, r, mixes) of every realistic scene × sensor × seed × size."""
    for shape, kinect_shape, seeds in QUICK_SIZES if quick else SIZES:
        for seed in seeds:
            for name in SCENES:
                videos: dict[tuple[int, int], Any] = {}
                for label, sensor, sigma, drop in SENSORS:
                    size = kinect_shape if sensor == "kinect" else shape
                    r = 2 if sensor == "kinect" else 4
                    if size not in videos:
                        videos[size] = make_realistic(
                            name, size, scale=r, n_frames=N_FRAMES, seed=seed
                        )
                    video = videos[size]
                    rng = np.random.default_rng([seed, zlib.crc32(f"{name}/{label}".encode())])
                    low = degrade(video, sensor, rng, sigma_mm=sigma, dropout_fraction=drop)
                    if sensor == "kinect":
                        low = np.round(low).astype(np.uint16)  # as the camera delivers it
                    tag = f"{name} {size[1]}×{size[0]} seed {seed} {label}"
                    yield tag, low, r, sensor == "tof"


def outside_videos(seeds: Sequence[int]) -> Iterator[tuple[str, np.ndarray, int, bool]]:
    """(label, low-res frames, r, mixes) of every scene and sensor of ``outside_eval.py``."""
    import outside_eval

    for cases in outside_eval.SCENES.values():
        for case in cases:
            video = case.build()
            for sensor in case.sensors:
                for seed in seeds:
                    low = outside_eval.sensor_input(video, case.name, sensor, seed)[:N_FRAMES]
                    if sensor.kind == "kinect":
                        low = low.astype(np.uint16)
                    tag = f"{case.name} seed {seed} {sensor.label}"
                    yield tag, low, video.scale, sensor.kind.startswith("tof")


def decisions(low: np.ndarray, r: int) -> dict[str, Any]:
    """The windowed decision and the recursive one after each of the first frames."""
    windowed = pinned_config(low[:N_FRAMES], UPSRConfig(scale=r, n_frames=N_FRAMES))
    engine = upsr.UPSR(r, N_FRAMES, mode="recursive", workers=0)
    recursive = []
    for frame in low[:N_FRAMES]:
        engine.push(frame)
        stats = engine.statistics
        recursive.append(bool(stats is not None and stats.remove_mixed))
    return {"windowed": bool(windowed.remove_mixed), "recursive": recursive}


def run(videos: Iterator[tuple[str, np.ndarray, int, bool]]) -> list[dict[str, Any]]:
    rows = []
    for tag, low, r, mixes in videos:
        rows.append({"video": tag, "mixes": mixes, **decisions(low, r)})
    return rows


def summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Wrong decisions: windowed; recursive after frames 1, 2, 3 and 9, and on any of the 9."""
    wrong = {"windowed": [r["video"] for r in rows if r["windowed"] != r["mixes"]]}
    for k in (1, 2, 3, N_FRAMES):
        wrong[f"recursive after {k}"] = [
            r["video"] for r in rows if r["recursive"][k - 1] != r["mixes"]
        ]
    wrong["recursive on any frame"] = [
        r["video"] for r in rows if any(d != r["mixes"] for d in r["recursive"])
    ]
    return {
        "videos": len(rows),
        "mixing": sum(r["mixes"] for r in rows),
        "wrong": wrong,
    }


def markdown(res: dict[str, Any]) -> str:
    lines = [
        "# Whether the sensor mixes depths at edges",
        "",
        f"`benchmarks/footprint_eval.py{' --quick' if res['quick'] else ''}` at "
        f'{res["commit"]}: the decision of `remove_mixed="auto"` against the sensor '
        "(ToF mixes; Laplace, Gauss, Kinect do not).",
        "",
        "| videos | mixing | decision | wrong | of which |",
        "|---|---|---|---|---|",
    ]
    for part in ("realistic", "outside"):
        s = res[part]
        for name, videos in s["wrong"].items():
            listed = ", ".join(videos[:12]) + (", …" if len(videos) > 12 else "")
            lines.append(
                f"| {part} ({s['videos']}) | {s['mixing']} | {name} | {len(videos)} | "
                f"{listed or '—'} |"
            )
    return "\n".join(lines) + "\n"


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="results/bench/footprint")
    p.add_argument("--quick", action="store_true", help="64×56 only, seeds 0–1; outside seed 0")
    args = p.parse_args(argv)
    t0 = time.perf_counter()
    from outside_eval import _commit, write_report

    res: dict[str, Any] = {"commit": _commit(), "quick": args.quick}
    for part, videos in (
        ("realistic", realistic_videos(args.quick)),
        ("outside", outside_videos((0,) if args.quick else (0, 1, 2))),
    ):
        rows = run(videos)
        res[part] = {**summary(rows), "rows": rows}
        print(f"{part}: {len(rows)} videos ({time.perf_counter() - t0:.0f} s)", flush=True)
    write_report(Path(args.out), res, markdown(res), t0)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
