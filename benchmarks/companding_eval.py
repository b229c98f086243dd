"""The companding of depth quantised in disparity (:mod:`upsr.method.companding`), measured.

Three parts, each a table of ``results.md`` and a key of ``results.json``:

* ``false_knees`` — frames whose depth is *not* quantised in disparity, for which
  :func:`~upsr.method.companding.knee_mm` must find no knee: walls and slanted walls with
  Laplacian / Gaussian noise of 0.3–100 mm at 1–15 m (float and whole mm, 8×10 to 160×120);
  clean and noisy renders of the realistic scenes at near and far depth (float and whole mm);
  clean planes slanted along the rows (1/z affine over the columns); depth quantised in depth
  (a LiDAR's 2–20 mm units) with noise. 2244 frames (the cases of an audit of 7 Dec 2026).
* ``missed_knees`` — frames of disparity-quantised cameras with far content (a Kinect, 1/8 px
  at f·b = 580 px · 75 mm; D435-like 1/32 and 1/8 px at 385 · 50; D415-like 1/32 px at 600 · 55)
  whose knee :func:`~upsr.method.companding.knee_mm` should find: a wall 0.5–3 m beyond the
  knee, fronto-parallel or slanted, with 0–85 % of the frame at 0.6–3.5 m, noise of the Kinect
  model or 0.3 / 1 / 3 level steps, float or whole mm (6144 frames). Reported per noise: those
  whose noise is well below a level step (0.3) are the fit's known limit.
* ``knee_steps`` — the Kinect scenes of ``outside_eval.py`` (static walls at 4–8 m, the
  corridor, the hand, the slanted scene) with :data:`~upsr.method.companding.KNEE_STEPS` at
  1.05 (the default), 1.2 and 1.5, both modes: surface rmse and edge accuracy.
* ``kernels`` — :func:`~upsr.method.companding.compand` / :func:`~upsr.method.companding.expand`
  on 1280×960 depths (half beyond the knee), median of 20 calls.

Example::

    .venv/bin/python benchmarks/companding_eval.py --out docs/results/companding
"""

from __future__ import annotations

import argparse
import collections
import dataclasses
import itertools
import math
import statistics
import sys
import time
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

import upsr.method.companding as companding
from upsr.research.synth.degradation import kinect_axial_sigma_mm, quantise_disparity
from upsr.research.synth.realistic import degrade, make_realistic

sys.path.insert(0, str(Path(__file__).resolve().parent))

__all__ = ["main"]

#: name -> (f px, b mm, disparity step px)
CAMERAS = {
    "kinect": (580.0, 75.0, 1 / 8),
    "d435_32": (385.0, 50.0, 1 / 32),
    "d435_8": (385.0, 50.0, 1 / 8),
    "d415_32": (600.0, 55.0, 1 / 32),
}


def continuous_frames() -> Iterator[tuple[str, np.ndarray]]:
    """(label, frame) of depth not quantised in disparity (the ``false_knees`` cases)."""
    rng = np.random.default_rng(0)
    for z0, sig, law, whole, shape, slant in itertools.product(
        (1000, 2000, 4000, 7000, 10000, 15000), (0.3, 1, 3, 10, 30, 100), ("laplace", "gauss"),
        (False, True), ((8, 10), (30, 40), (120, 160)), (0.0, 0.5, 2.0),
    ):  # fmt: skip
        h, w = shape
        z = z0 * (1 + slant * np.arange(w)[None, :] / w) * np.ones((h, 1))
        if law == "laplace":
            z = z + rng.laplace(0, sig / math.sqrt(2), z.shape)
        else:
            z = z + rng.normal(0, sig, z.shape)
        yield "wall with ToF-like noise", np.round(z) if whole else z
    for name, seed, (body, wall) in itertools.product(
        ("gallop", "deforming", "toward_wall", "room", "fan"), range(3),
        ((2000, 3000), (5000, 7000), (6000, 9000), (8000, 14000)),
    ):  # fmt: skip
        kw: dict[str, float] = {}
        if name in ("gallop", "deforming"):
            kw = {"body_depth_mm": body, "wall_depth_mm": wall}
        elif name == "toward_wall":
            kw = {"wall_depth_mm": wall}
        video = make_realistic(name, (40, 48), scale=2, n_frames=2, seed=seed, **kw)
        for sensor, sig in (("clean", 0), ("laplace", 5), ("gaussian", 5), ("tof", 2),
                            ("tof", 10), ("tof_gaussian", 5)):  # fmt: skip
            low = degrade(video, sensor, np.random.default_rng(seed), sigma_mm=max(sig, 1e-3))[0]
            yield "realistic scene, continuous sensor", low
            yield "realistic scene, continuous sensor, whole mm", np.round(low)
    for near, far, w, h, whole in itertools.product(
        (1500, 3000, 5000, 7000), (6000, 9000, 12000, 20000), (40, 64, 160), (30, 120),
        (False, True),
    ):  # fmt: skip
        if far > near:
            plane = np.ones((h, 1)) / np.linspace(1 / near, 1 / far, w)[None, :]
            yield "clean plane slanted along the rows", np.round(plane) if whole else plane
    for z0, unit, sig in itertools.product((3000, 8000, 15000), (2, 4, 10, 20), (0, 1, 5, 20)):
        z = z0 * (1 + 0.5 * np.arange(64)[None, :] / 64) * np.ones((48, 1))
        z = z + rng.normal(0, sig + 1e-9, z.shape)
        yield "depth quantised in depth units", unit * np.round(z / unit)


def quantised_frames() -> Iterator[tuple[str, np.ndarray]]:
    """(noise label, frame) of disparity-quantised cameras with far content."""
    rng = np.random.default_rng(0)
    for (f, b, step), near_share, z_near, beyond, noise, whole, shape, slant in itertools.product(
        CAMERAS.values(), (0.0, 0.3, 0.6, 0.85), (600, 1000, 2000, 3500), (500, 1500, 3000),
        ("kinect", 0.3, 1.0, 3.0), (True, False), ((30, 40), (120, 160)), (False, True),
    ):  # fmt: skip
        alpha = step / (f * b)
        h, w = shape
        z = np.full((h, w), math.sqrt(100.0 / (companding.KNEE_STEPS * alpha)) + beyond)
        if slant:
            z = z * (1 + 0.3 * np.arange(w)[None, :] / w)
        z[:, : round(near_share * w)] = z_near
        sigma = kinect_axial_sigma_mm(z) if noise == "kinect" else noise * alpha * z**2
        q = quantise_disparity(z + rng.normal(0, 1, z.shape) * sigma, focal_px=f,
                               baseline_mm=b, step_px=step)  # fmt: skip
        label = "Kinect model" if noise == "kinect" else f"{noise:g} level steps"
        yield label, np.round(q) if whole else q


def knee_counts(frames: Iterator[tuple[str, np.ndarray]], want: bool) -> dict[str, list[int]]:
    """label -> [frames whose knee is not as wanted, frames]."""
    out: dict[str, list[int]] = collections.defaultdict(lambda: [0, 0])
    for label, frame in frames:
        found = math.isfinite(companding.knee_mm(frame, 100.0))
        out[label][0] += found != want
        out[label][1] += 1
    return dict(out)


def knee_steps(values: Sequence[float]) -> list[dict[str, Any]]:
    """The Kinect rows of ``outside_eval.py`` with KNEE_STEPS at each of ``values``."""
    import outside_eval

    rows = []
    default = companding.KNEE_STEPS
    try:
        for steps in values:
            companding.KNEE_STEPS = steps  # (read by knee_mm at each call)
            for cases in outside_eval.SCENES.values():
                for case in cases:
                    sensors = [s for s in case.sensors if s.kind == "kinect"]
                    for sensor in sensors:
                        one = dataclasses.replace(case, sensors=(sensor,))
                        for row in outside_eval.run_case(one, 0, time.perf_counter()):
                            if row["method"] in ("upsr", "upsr_recursive"):
                                rows.append({"knee_steps": steps, **row})
    finally:
        companding.KNEE_STEPS = default
    return rows


def kernel_ms() -> dict[str, float]:
    """Median ms of compand / expand on 1280×960 depths, half beyond a 5.76 m knee."""
    z = np.random.default_rng(0).uniform(1000.0, 9000.0, (960, 1280)).astype(np.float32)
    u = companding.compand(z, 5760.0)
    out = {}
    for name, fn, arr in (("compand", companding.compand, z), ("expand", companding.expand, u)):
        times = []
        for _ in range(20):
            t0 = time.perf_counter()
            fn(arr, 5760.0)
            times.append(1e3 * (time.perf_counter() - t0))
        out[name] = statistics.median(times)
    return out


def markdown(res: dict[str, Any]) -> str:
    from realistic_eval import _fmt

    lines = ["# The companding of depth quantised in disparity", "",
             f"`benchmarks/companding_eval.py` at {res['commit']}. Knees fitted at the 100 mm "
             "edge step.", "",
             "## Continuous depth: false knees", "", "| frames | false knees | of |",
             "|---|---:|---:|"]  # fmt: skip
    for label, (bad, n) in res["false_knees"].items():
        lines.append(f"| {label} | {bad} | {n} |")
    lines += ["", "## Disparity-quantised cameras with far content: missed knees", "",
              "| noise | missed | of |", "|---|---:|---:|"]  # fmt: skip
    for label, (bad, n) in res["missed_knees"].items():
        lines.append(f"| {label} | {bad} | {n} |")
    lines += ["", "## Kinect scenes of outside_eval.py by KNEE_STEPS", "",
              "| KNEE_STEPS | scene | method | rmse | surface rmse | edge accuracy % |",
              "|---:|---|---|---:|---:|---:|"]  # fmt: skip
    for r in res["knee_steps"]:
        edge_s = _fmt(r["edge_accuracy"], "edge_accuracy")
        lines.append(f"| {r['knee_steps']:g} | {r['scene']} | {r['method']} | {r['rmse']:.1f} | "
                     f"{r['surface_rmse']:.1f} | {edge_s} |")  # fmt: skip
    k = res["kernels_ms"]
    lines += ["", f"Kernels on 1280×960 (median of 20): compand {k['compand']:.2f} ms, "
              f"expand {k['expand']:.2f} ms.", ""]  # fmt: skip
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="results/bench/companding")
    p.add_argument("--quick", action="store_true", help="no KNEE_STEPS runs")
    args = p.parse_args(argv)
    t0 = time.perf_counter()
    from outside_eval import _commit, write_report

    res: dict[str, Any] = {
        "commit": _commit(),
        "false_knees": knee_counts(continuous_frames(), want=False),
        "missed_knees": knee_counts(quantised_frames(), want=True),
        "knee_steps": [] if args.quick else knee_steps((1.05, 1.2, 1.5)),
        "kernels_ms": kernel_ms(),
    }
    write_report(Path(args.out), res, markdown(res), t0)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
