"""End-to-end demonstration on a synthetic dynamic scene with known ground truth.

Synthesises a short noisy low-res depth video of a non-rigidly moving object in front of a
wall (:func:`upsr.research.synth.dynamic_scene`), super-resolves it with UP-SR
(:func:`upsr.method.windowed.super_resolve`) and with the single-frame baselines of paper §7
(:mod:`upsr.research.baselines`), scores all of them against the truth
(:mod:`upsr.research.metrics`) and writes a picture and the numbers.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from upsr._atomic import write_text_atomic
from upsr.errors import InputError
from upsr.method.windowed import super_resolve
from upsr.research import baselines
from upsr.research.metrics import evaluate
from upsr.research.synth import dynamic_scene
from upsr.viz.colormaps import colorbar, colorize_depth, colorize_error, panel_grid, write_png

__all__ = ["METRIC_COLUMNS", "format_metrics_table", "run_demo"]

#: Metrics written to ``metrics.csv`` and printed by :func:`format_metrics_table`.
METRIC_COLUMNS = (
    "rmse",
    "mse",
    "surface_rmse",
    "edge_accuracy",
    "flying_pixels",
    "missing",
    "invented",
)
_UNITS = {"rmse": "mm", "mse": "mm^2", "surface_rmse": "mm"}
METHODS = ("nearest", "bicubic", "upsr")


def _json_safe(obj: Any) -> Any:
    """NaN / inf → None (strict JSON), numpy scalars → Python numbers."""
    if isinstance(obj, dict):
        return {k: _json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_json_safe(v) for v in obj]
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


def _demo_figure(
    lowres: np.ndarray,
    bicubic: np.ndarray,
    upsr: np.ndarray,
    truth: np.ndarray,
    min_height_px: int = 360,
) -> np.ndarray:
    """One row: low-res, bicubic, UP-SR, truth (shared depth colours), error, colour bars."""
    valid = truth[truth > 0]
    vmin = float(np.floor(valid.min() / 100.0) * 100.0) if valid.size else 0.0
    vmax = float(np.ceil(valid.max() / 100.0) * 100.0) if valid.size else 1.0
    vmax = max(vmax, vmin + 100.0)
    both = (upsr > 0) & (truth > 0)
    err = np.where(both, np.abs(upsr - truth), np.nan)
    err_max = 100.0
    hr_h = truth.shape[0]
    k = max(1, -(-min_height_px // hr_h))  # panels are enlarged to k·hr_h
    panels = [
        ("low-res input", colorize_depth(lowres, vmin, vmax)),
        ("bicubic", colorize_depth(bicubic, vmin, vmax)),
        ("UP-SR", colorize_depth(upsr, vmin, vmax)),
        ("ground truth", colorize_depth(truth, vmin, vmax)),
        ("|UP-SR - truth|", colorize_error(err, err_max)),
    ]
    row = panel_grid(panels, min_height_px=k * hr_h)
    title_h = row.shape[0] - k * hr_h
    bars = [
        colorbar(k * hr_h, vmin, vmax, "depth mm"),
        colorbar(k * hr_h, 0.0, err_max, "err mm", colormap=cv2.COLORMAP_VIRIDIS),
    ]
    cells = []
    for bar in bars:
        cell = np.full((row.shape[0], bar.shape[1], 3), 255, np.uint8)
        cell[title_h:] = bar
        cells.append(cell)
    gap = np.full((row.shape[0], 6, 3), 255, np.uint8)
    out = np.hstack([row, gap, cells[0], gap, cells[1]])
    note = np.full((22, out.shape[1], 3), 255, np.uint8)
    cv2.putText(
        note,
        "black = no depth / no value",
        (6, 15),
        cv2.FONT_HERSHEY_SIMPLEX,
        0.45,
        (0, 0, 0),
        1,
        cv2.LINE_AA,
    )
    return np.vstack([out, note])


def run_demo(
    out_dir: str | os.PathLike[str],
    *,
    seed: int = 0,
    scale: int = 4,
    n_frames: int = 9,
    noise_sigma_mm: float = 30.0,
    progress: bool = True,
    n_total_frames: int = 15,
    lowres_shape: tuple[int, int] = (48, 64),
    motion_px: float = 1.5,
) -> dict[str, Any]:
    """Run the synthetic UP-SR demonstration and write its results into ``out_dir``.

    Parameters
    ----------
    out_dir : path-like
        Folder for ``demo.png``, ``metrics.csv`` and ``metrics.json`` (created if needed).
    seed : int
        Seed of the scene and of the noise.
    scale : int
        SR factor r.
    n_frames : int
        UP-SR window length N (frames fused per output frame).
    noise_sigma_mm : float
        Standard deviation σ (mm) of the Laplacian noise of the low-res input.
    progress : bool
        Show the pipeline's progress bar.
    n_total_frames : int
        Length T of the synthetic video (≥ ``n_frames`` gives full sliding windows).
    lowres_shape : (int, int)
        Low-res frame size (h, w) in px.
    motion_px : float
        Speed of the moving object (low-res px / frame).

    Returns
    -------
    dict
        ``{"config": {...}, "middle_frame": {method: metrics}, "all_frames": {method: metrics},
        "timing_s": {...}, "files": {...}}`` with methods ``nearest``, ``bicubic``, ``upsr``
        and metrics as returned by :func:`upsr.research.metrics.evaluate` (``all_frames`` pools the
        pixels of every frame).

    Notes
    -----
    ``demo.png``: the middle frame; low-res input (blocky), bicubic, UP-SR, truth, and
    |UP-SR − truth| with colour bars (black = no value). ``metrics.csv``: one row per
    (method, frames ∈ {middle, all}) with :data:`METRIC_COLUMNS`. ``metrics.json``: the returned
    dict (NaN written as null).
    """
    if (
        isinstance(n_total_frames, bool)
        or not isinstance(n_total_frames, (int, np.integer))
        or n_total_frames < 1
    ):
        raise InputError(f"n_total_frames must be an integer >= 1, got {n_total_frames!r}")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    video = dynamic_scene(
        n_frames=n_total_frames,
        lowres_shape=lowres_shape,
        scale=scale,
        noise_sigma_mm=noise_sigma_mm,
        seed=seed,
        motion_px=motion_px,
    )
    t1 = time.perf_counter()
    estimates, (t2, t3) = _estimates(video, scale, n_frames, progress)
    mid = video.n_frames // 2
    middle = {m: evaluate(est[mid], video.truth[mid], scale) for m, est in estimates.items()}
    pooled = {m: evaluate(est, video.truth, scale) for m, est in estimates.items()}
    t4 = time.perf_counter()

    figure = _demo_figure(
        video.lowres[mid], estimates["bicubic"][mid], estimates["upsr"][mid], video.truth[mid]
    )
    png = write_png(out / "demo.png", figure)

    _write_metrics_csv(out / "metrics.csv", middle, pooled)

    result: dict[str, Any] = {
        "config": {
            "seed": seed,
            "scale": scale,
            "n_frames": n_frames,
            "noise_sigma_mm": noise_sigma_mm,
            "n_total_frames": n_total_frames,
            "lowres_shape": list(lowres_shape),
            "motion_px": motion_px,
            "middle_frame_index": mid,
        },
        "middle_frame": middle,
        "all_frames": pooled,
        "timing_s": {
            "synthesis": t1 - t0,
            "baselines": t2 - t1,
            "upsr": t3 - t2,
            "metrics": t4 - t3,
            "total": time.perf_counter() - t0,
        },
        "files": {
            "png": str(png),
            "csv": str(out / "metrics.csv"),
            "json": str(out / "metrics.json"),
        },
    }
    write_text_atomic(
        out / "metrics.json", json.dumps(_json_safe(result), indent=2, allow_nan=False) + "\n"
    )
    return result


def _estimates(
    video: Any, scale: int, n_frames: int, progress: bool
) -> tuple[dict[str, np.ndarray], tuple[float, float]]:
    """Nearest, bicubic and UP-SR of ``video.lowres`` (T, h, w) mm, each (T, r*h, r*w) mm.

    Also returns the times (:func:`time.perf_counter`) when the baselines, then UP-SR, finished.
    """
    estimates = {
        "nearest": baselines.nearest(video.lowres, scale),
        "bicubic": baselines.bicubic(video.lowres, scale),
    }
    t2 = time.perf_counter()
    estimates["upsr"] = np.asarray(
        super_resolve(video.lowres, scale, n_frames, progress=progress), np.float32
    )
    t3 = time.perf_counter()
    if estimates["upsr"].shape != video.truth.shape:
        raise RuntimeError(
            f"super_resolve returned shape {estimates['upsr'].shape}, expected {video.truth.shape}"
        )
    return estimates, (t2, t3)


def _write_metrics_csv(
    path: Path, middle: dict[str, dict[str, Any]], pooled: dict[str, dict[str, Any]]
) -> None:
    """Write ``metrics.csv``: one row per (method, frames: middle or all), METRIC_COLUMNS."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(["method", "frames", *METRIC_COLUMNS])
    for label, table in (("middle", middle), ("all", pooled)):
        for method, res in table.items():
            writer.writerow([method, label, *(f"{res[c]:.6g}" for c in METRIC_COLUMNS)])
    write_text_atomic(path, buf.getvalue())


def format_metrics_table(metrics: dict[str, Any]) -> str:
    """Fixed-width text table of the metrics returned by :func:`run_demo`.

    Accepts the full :func:`run_demo` result (one block per frame selection) or a plain
    ``{method: {metric: value}}`` mapping. NaN prints as ``n/a``.
    """
    if "middle_frame" in metrics or "all_frames" in metrics:
        blocks = [
            (
                f"middle frame (t = {metrics.get('config', {}).get('middle_frame_index', '?')})",
                metrics.get("middle_frame", {}),
            ),
            ("all frames (pooled)", metrics.get("all_frames", {})),
        ]
    else:
        blocks = [("", metrics)]
    headers = [c + (f" [{_UNITS[c]}]" if c in _UNITS else "") for c in METRIC_COLUMNS]
    widths = [max(len(h), 9) + 2 for h in headers]
    name_w = max([len("method")] + [len(m) for _, b in blocks for m in b]) + 2
    lines = []
    for title, table in blocks:
        if not table:
            continue
        if title:
            lines.append(title)
        lines.append(
            "method".ljust(name_w)
            + "".join(h.rjust(w) for h, w in zip(headers, widths, strict=True))
        )
        for method, res in table.items():
            cells = []
            for c, w in zip(METRIC_COLUMNS, widths, strict=True):
                v = res.get(c, math.nan)
                cells.append(("n/a" if v is None or not math.isfinite(v) else f"{v:.4g}").rjust(w))
            lines.append(method.ljust(name_w) + "".join(cells))
        lines.append("")
    return "\n".join(lines).rstrip("\n")
