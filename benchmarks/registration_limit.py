"""How well can point samples be registered locally? A known sub-pixel translation.

An analytic scene (a wall at 3 m, a rotated box at 1.5 m, a disc at 2 m, a bar 7 output px
wide at 1.2 m) moves by a known random sub-pixel 2-D shift per frame (uniform in [0, 2r)
output px); each low-res frame samples it at its pixel centres (``SPEC.md`` §1), with
Laplacian noise of σ (``--sigma``). Rows: ``nearest``, ``bicubic``, ``upsr`` (the defaults:
the flow) and ``upsr_exact`` (every map of every window the exact shift:
:func:`exact_shifts`), with SPEC §6's metrics and the misplaced pixels per pixel of an edge
line (``registration_oracle.misplaced_per_edge_px``).

Then the flow's maps against the exact shift near the edges (the truth's gradient above 30 %
of its maximum, on the flow grid), split into the component across the edge (``normal``: it
moves the edge) and along it (``tangential``: it does not), in low-res px; and the same after
a local re-registration against the *truth* (:func:`reregister`: each output pixel's shift
corrected by the offset within ±0.5 low-res px, in steps of 1/4, that makes the frame's
nearest samples agree best with the truth over a window of ±2 low-res px): the information a
local window of point samples holds about its own shift.

Example::

    .venv/bin/python benchmarks/registration_limit.py --seeds 0 1 --sigma 0 10 \\
        --out docs/results/registration_limit
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np

import upsr
from registration_oracle import captured_maps, misplaced_per_edge_px, window_maps
from upsr.research import baselines
from upsr.research.metrics import evaluate

R, H, W, N = 4, 56, 64, 9
METRICS = ("rmse", "surface_rmse", "edge_accuracy", "flying_pixels")


def scene(x: np.ndarray, y: np.ndarray, angle: float = 0.3) -> np.ndarray:
    """Depth (mm) of the analytic scene at output-px coordinates (x, y)."""
    z = np.full(np.shape(x), 3000.0)
    c, s = np.cos(angle), np.sin(angle)
    u, v = (x - 90) * c + (y - 100) * s, -(x - 90) * s + (y - 100) * c
    z[(np.abs(u) < 45) & (np.abs(v) < 30)] = 1500.0
    z[(x - 190) ** 2 + (y - 120) ** 2 < 40**2] = 2000.0
    z[(np.abs(x - 150) < 3.5) & (y > 20) & (y < 200)] = 1200.0
    return z


def make_video(seed: int, sigma: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(shifts (N, 2) output px as (x, y), truth (N, R·H, R·W), low-res frames (N, H, W))."""
    rng = np.random.default_rng(seed)
    shifts = rng.uniform(0, 2 * R, size=(N, 2))
    ys, xs = np.mgrid[0 : H * R, 0 : W * R].astype(float)
    ly, lx = np.mgrid[0:H, 0:W].astype(float)
    cx, cy = (lx + 0.5) * R - 0.5, (ly + 0.5) * R - 0.5
    truth = np.stack([scene(xs + sx, ys + sy) for sx, sy in shifts]).astype(np.float32)
    low = np.stack([scene(cx + sx, cy + sy) for sx, sy in shifts]).astype(np.float32)
    if sigma:
        low += rng.laplace(0.0, sigma / np.sqrt(2.0), low.shape).astype(np.float32)
    return shifts, truth, low


def exact_shifts(shifts: np.ndarray) -> contextlib.AbstractContextManager[None]:
    """Replace the windowed engine's maps by the exact shifts (any flow grid)."""

    def make(window, _):  # type: ignore[no-untyped-def]
        def _cumulative(ref, backward, forward, shape, *, out, **_):  # type: ignore[no-untyped-def]
            t, s0, grid = window["t"], window["s"], shape[0] / H
            for i in range(len(out)):
                out[i] = (shifts[t] - shifts[s0 + i]) * grid / R
            return list(out)

        return _cumulative

    return window_maps(make)


def reregister(
    shift_map: np.ndarray, frame: np.ndarray, truth: np.ndarray, edge_mm: float = 100.0
) -> np.ndarray:
    """``shift_map`` (R·H, R·W, 2, output px) corrected per output pixel by the offset within
    ±0.5 low-res px (steps of 1/4) whose nearest samples of ``frame`` agree best with
    ``truth`` (mean of min(|Δ|, edge)/edge over ±2 low-res px), where it beats no offset."""
    hh, ww = truth.shape
    ys, xs = np.mgrid[0:hh, 0:ww].astype(np.float32)
    box = (4 * R + 1, 4 * R + 1)
    costs, offsets = [], []
    for dy in np.arange(-0.5, 0.51, 0.25):
        for dx in np.arange(-0.5, 0.51, 0.25):
            px, py = xs + shift_map[..., 0] + dx * R, ys + shift_map[..., 1] + dy * R
            j = np.clip(np.rint((px + 0.5) / R - 0.5).astype(int), 0, W - 1)
            i = np.clip(np.rint((py + 0.5) / R - 0.5).astype(int), 0, H - 1)
            z = frame[i, j]
            ok = ((z > 0) & (truth > 0)).astype(np.float32)
            cost = ok * np.minimum(np.abs(z - truth), edge_mm) / edge_mm
            total = cv2.boxFilter(cost.astype(np.float32), -1, box, normalize=False)
            count = cv2.boxFilter(ok, -1, box, normalize=False)
            costs.append(total / np.maximum(count, 1.0))
            offsets.append((dx * R, dy * R))
    c = np.stack(costs)
    best = np.argmin(c, axis=0)
    still = offsets.index((0.0, 0.0))
    best = np.where(np.take_along_axis(c, best[None], 0)[0] < c[still], best, still)
    return shift_map + np.asarray(offsets, np.float32)[best]


def map_errors(
    shifts: np.ndarray, truth: np.ndarray, low: np.ndarray, store: list
) -> dict[str, float]:
    """Median / 90th percentile |error| (low-res px) of the flow's maps near the edges,
    across and along them, before and after :func:`reregister` against the truth."""
    parts: dict[str, list[np.ndarray]] = {k: [] for k in ("normal", "tangential", "normal_re")}
    for t, s0, maps in store:
        z = cv2.GaussianBlur(truth[t], (0, 0), 2.0)
        gx, gy = cv2.Sobel(z, cv2.CV_32F, 1, 0), cv2.Sobel(z, cv2.CV_32F, 0, 1)
        mag = np.hypot(gx, gy)
        edge = mag > 0.3 * mag.max()
        nx, ny = gx / np.maximum(mag, 1e-6), gy / np.maximum(mag, 1e-6)
        for i in range(len(maps)):
            if s0 + i == t:
                continue
            exact = (shifts[t] - shifts[s0 + i]).astype(np.float32)
            est = cv2.resize(maps[i], truth.shape[::-1][:2], interpolation=cv2.INTER_LINEAR)
            est *= R * H / maps.shape[1]  # output px
            for key, m in (("", est), ("_re", reregister(est, low[s0 + i], truth[t]))):
                err = (m - exact) / R
                parts["normal" + key].append(np.abs(err[..., 0] * nx + err[..., 1] * ny)[edge])
                if not key:
                    tang = np.abs(-err[..., 0] * ny + err[..., 1] * nx)[edge]
                    parts["tangential"].append(tang)
    out = {}
    for key, vals in parts.items():
        v = np.concatenate(vals)
        out[f"{key}_median"], out[f"{key}_p90"] = float(np.median(v)), float(np.quantile(v, 0.9))
    return out


def run_case(seed: int, sigma: float) -> tuple[list[dict[str, Any]], dict[str, float]]:
    shifts, truth, low = make_video(seed, sigma)
    store: list = []
    with captured_maps(store):
        flow = np.stack(list(upsr.UPSR(R, N, workers=0).process(low)))
    with exact_shifts(shifts):
        exact = np.stack(list(upsr.UPSR(R, N, workers=0).process(low)))
    outs = {
        "nearest": baselines.nearest(low, R),
        "bicubic": baselines.bicubic(low, R),
        "upsr": flow,
        "upsr_exact": exact,
    }
    rows = []
    for method, est in outs.items():
        m = evaluate(est, truth, R)
        row = {"seed": seed, "sigma": sigma, "method": method}
        row.update({k: float(m[k]) for k in METRICS})
        row["misplaced_per_edge_px"] = misplaced_per_edge_px(est, truth)
        rows.append(row)
    errors = {"seed": seed, "sigma": sigma, **map_errors(shifts, truth, low, store)}
    return rows, errors


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", nargs="+", type=int, default=[0, 1])
    p.add_argument("--sigma", nargs="+", type=float, default=[0.0, 10.0], help="noise σ (mm)")
    p.add_argument("--out", type=Path, default=Path("results/registration_limit"))
    args = p.parse_args(argv)
    rows, errors = [], []
    for seed in args.seeds:
        for sigma in args.sigma:
            r, e = run_case(seed, sigma)
            rows += r
            errors.append(e)
    lines = [
        "| seed | σ | method | rmse | surface | edge % | flying % | misplaced / edge px |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['seed']} | {r['sigma']:g} | {r['method']} | {r['rmse']:.2f} | "
            f"{r['surface_rmse']:.2f} | {100 * r['edge_accuracy']:.2f} | "
            f"{100 * r['flying_pixels']:.2f} | {r['misplaced_per_edge_px']:.3f} |"
        )
    lines += [
        "",
        "| seed | σ | across the edge: median / p90 | along it | across, re-registered "
        "against the truth |",
        "|---|---|---|---|---|",
    ]
    for e in errors:
        lines.append(
            f"| {e['seed']} | {e['sigma']:g} | {e['normal_median']:.3f} / {e['normal_p90']:.3f} "
            f"| {e['tangential_median']:.3f} / {e['tangential_p90']:.3f} "
            f"| {e['normal_re_median']:.3f} / {e['normal_re_p90']:.3f} |"
        )
    table = "\n".join(lines)
    print(table)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "results.md").write_text(table + "\n")
    (args.out / "results.json").write_text(
        json.dumps({"rows": rows, "map_errors": errors}, indent=1)
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
