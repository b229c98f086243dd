"""MSE vs noise level on Samba for every method (paper §7.3–7.4, Fig. 3 and 6).

Protocol. Nine consecutive Samba meshes (``mesh_0000`` … ``mesh_0008``) are rendered with one
fixed camera at 1024×588 (ground truth) and at 256×147 with the same field of view (the input,
r = 4, ``SPEC.md`` §1 pixel geometry), as in ``benchmarks/samba_eval.py``; no background
(depth 0). Laplacian noise of standard deviation σ = 0, 10, …, 100 mm is added to the valid
input pixels. Every method super-resolves the 9-frame clip (multi-frame methods with N = 9:
each output frame fuses all nine frames, reference in the window, as UP-SR does) and is scored
on all nine output frames pooled (:func:`upsr.research.metrics.evaluate`: MSE over the pixels
valid in both truth and output, and the other SPEC §6 metrics).

Methods: ``nearest``, ``bicubic``, ``bicubic_noflying`` (flying pixels removed with a fixed
100 mm threshold), ``shift_add`` (dynamic median Shift & Add), ``lidarboost``, ``sisr``
(patch-based single-image SR, the dictionary of :func:`upsr.research.baselines.train_patch_sisr`),
``upsr_fused`` (UP-SR without deblurring), ``upsr`` (UP-SR with the deblurring parameters
chosen per σ, see below) and ``upsr_default`` (UP-SR with its default parameters); all three
end, as :class:`upsr.UPSR` does, with the removal of isolated outliers
(:func:`upsr.method.outliers.remove_speckles`). Shift & Add
and LidarBoost use UP-SR's motion (:func:`upsr.research.baselines.upsampled_flows`).

Deblurring parameters. The paper picks them by an exhaustive search for the smallest error on
the test data itself. Here they are chosen per σ on a *held-out* frame: the centre frame of the
next nine meshes (``mesh_0009`` … ``mesh_0017``, independent noise), fused by UP-SR and
deblurred with every combination of λ ∈ {0.1, 0.3, 0.5, 1, 2} and the final surface smoothing
off (the paper's plain L1+BTV) or on with a range σ of 30 mm (UP-SR's default), 60 or 100 mm
(a wider range also smooths the steep slopes of a body near its silhouette; it is safe only
where no two surfaces are that close in depth, which the held-out frame and the flying-pixel
metric check); the combination with the smallest MSE on that frame is then used on the
evaluation clip (``noise_deblur_search.csv`` lists the search).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from upsr.errors import InputError
from upsr.method.config import DeblurConfig, UPSRConfig
from upsr.method.finishing import finish_fused
from upsr.method.smoothing import smooth_output
from upsr.method.windowed import super_resolve
from upsr.research import baselines
from upsr.research.experiments.common import (
    DEFAULT_DATA,
    ExperimentResult,
    Logger,
    check_out_dir,
    markdown_table,
    null_logger,
    write_csv,
    write_plot,
    write_summary,
)
from upsr.research.experiments.data import render_samba, samba_mesh_paths
from upsr.research.metrics import evaluate
from upsr.research.synth import add_laplacian_noise
from upsr.viz.figures import PALETTE, LinePlot, Series, line_plot

__all__ = ["DEBLUR_GRID", "METHODS", "run_noise", "search_deblur"]

NAME = "noise"
TITLE = "MSE vs noise on Samba, all methods (paper Fig. 6)"
METHODS: tuple[str, ...] = (
    "nearest",
    "bicubic",
    "bicubic_noflying",
    "shift_add",
    "lidarboost",
    "sisr",
    "upsr_fused",
    "upsr",
    "upsr_default",
)
METRICS = ("mse", "rmse", "surface_rmse", "edge_accuracy", "flying_pixels", "missing", "invented")
CSV_COLUMNS = (
    "method",
    "sigma",
    *METRICS,
    "deblur_lam",
    "deblur_smooth_mm",
    "seconds",
)
SEARCH_COLUMNS = ("sigma", "lam", "smooth_sigma_mm", "heldout_mse", "chosen")

#: The deblurring search: (λ, final smoothing range σ in mm or None).
DEBLUR_GRID: tuple[tuple[float, float | None], ...] = tuple(
    (lam, smooth) for lam in (0.1, 0.3, 0.5, 1.0, 2.0) for smooth in (None, 30.0, 60.0, 100.0)
)
QUICK_DEBLUR_GRID: tuple[tuple[float, float | None], ...] = ((0.3, 30.0), (1.0, None))

SCALE = 4
N_FRAMES = 9
HR_SIZE = (1024, 588)
SIGMAS: tuple[float, ...] = tuple(float(s) for s in range(0, 101, 10))
QUICK_N_FRAMES = 5
QUICK_HR_SIZE = (64, 48)
QUICK_SIGMAS: tuple[float, ...] = (0.0, 50.0)


def search_deblur(
    fused: np.ndarray,
    truth: np.ndarray,
    r: int,
    grid: Sequence[tuple[float, float | None]] = DEBLUR_GRID,
) -> tuple[DeblurConfig, list[dict[str, Any]]]:
    """Pick the deblurring parameters with the smallest MSE on one (held-out) fused frame.

    Parameters
    ----------
    fused : ndarray (H, W)
        UP-SR's fused frame (no deblurring), mm.
    truth : ndarray (H, W)
        Its ground truth.
    r : int
        SR factor.
    grid : sequence of (lam, smooth_sigma_mm)
        Candidates; the other :class:`DeblurConfig` fields keep their defaults.

    Returns
    -------
    best : DeblurConfig
    rows : list of dict
        ``lam``, ``smooth_sigma_mm``, ``heldout_mse``, ``chosen`` for every candidate.
    """
    rows = []
    best: tuple[float, DeblurConfig] | None = None
    for lam, smooth in grid:
        cfg = DeblurConfig(lam=lam, smooth_sigma_mm=smooth)
        err = evaluate(_deblur_frame(fused, cfg, r), truth, r)["mse"]
        rows.append({"lam": lam, "smooth_sigma_mm": smooth, "heldout_mse": err, "chosen": False})
        if best is None or err < best[0]:
            best = (err, cfg)
    assert best is not None
    for row in rows:
        row["chosen"] = (
            row["lam"] == best[1].lam and row["smooth_sigma_mm"] == best[1].smooth_sigma_mm
        )
    return best[1], rows


def _deblur_frame(fused: np.ndarray, cfg: DeblurConfig, r: int) -> np.ndarray:
    """UP-SR's last steps on a fused frame with ``cfg``
    (:func:`upsr.method.finishing.finish_fused`, then the final smoothing,
    :func:`upsr.method.smoothing.smooth_output`)."""
    return smooth_output(finish_fused(fused, UPSRConfig(scale=r, deblur=cfg)), cfg, r)


def _deblur_video(fused: np.ndarray, cfg: DeblurConfig, r: int) -> np.ndarray:
    return np.stack([_deblur_frame(f, cfg, r) for f in fused])


def run_noise(
    out: str | os.PathLike[str] = "results/noise",
    data: str | os.PathLike[str] = DEFAULT_DATA,
    *,
    quick: bool = False,
    sigmas: Sequence[float] | None = None,
    methods: Sequence[str] = METHODS,
    seed: int = 0,
    log: Logger = null_logger,
) -> ExperimentResult:
    """Run the Fig. 6 experiment and write its files into ``out``.

    Files: ``noise.csv`` (long form: method, sigma, mse and the SPEC §6 metrics, the chosen
    deblurring parameters, seconds), ``noise_deblur_search.csv``, ``noise.png`` and ``noise.svg``
    (MSE vs σ, log scale), ``summary.md``.

    Parameters
    ----------
    out : path-like
        Output folder (created; renders are cached in ``out/cache``).
    data : path-like
        Shared data folder (``samba/mesh_XXXX.obj``).
    quick : bool
        5 frames rendered at 64×48 (input 16×12), σ = 0 and 50 mm, a 2-point search (seconds).
    sigmas : sequence of float, optional
        Noise levels (mm); default 0, 10, …, 100.
    methods : sequence of str
        Subset of :data:`METHODS` (``upsr`` needs ``upsr_fused``'s fusion, computed anyway).
    seed : int
        Noise seed.
    log : callable
        Progress messages.
    """
    unknown = sorted(set(methods) - set(METHODS))
    if unknown:
        raise InputError(
            f"unknown method(s) {', '.join(unknown)} (choose from {', '.join(METHODS)})"
        )
    out_dir = check_out_dir(out)
    n = QUICK_N_FRAMES if quick else N_FRAMES
    width, height = QUICK_HR_SIZE if quick else HR_SIZE
    r = SCALE
    paths = samba_mesh_paths(data, 0, 2 * n)
    render = render_samba(
        paths, width=width, height=height, scales=(r,), cache_dir=out_dir / "cache", log=log
    )
    truth, clean = render.truth[:n], render.lowres[r][:n]
    truth_h, clean_h = render.truth[n:], render.lowres[r][n:]
    grid = QUICK_DEBLUR_GRID if quick else DEBLUR_GRID
    sig = tuple(sigmas) if sigmas is not None else (QUICK_SIGMAS if quick else SIGMAS)
    sisr_model = baselines.train_patch_sisr(r, n_examples=2000 if quick else 60000, seed=seed)
    log(
        f"Samba {paths[0].name}..{paths[n - 1].name} (held out: {paths[n].name}.."
        f"{paths[-1].name}), {clean.shape[2]}x{clean.shape[1]} -> {width}x{height}, "
        f"r = {r}, N = {n}, sigma = {', '.join(f'{s:g}' for s in sig)} mm"
    )
    rows: list[dict[str, Any]] = []
    search_rows: list[dict[str, Any]] = []
    for sigma in sig:
        level_rows, level_search = _noise_level(
            float(sigma),
            (clean, truth),
            (clean_h, truth_h),
            r=r,
            n=n,
            grid=grid,
            methods=methods,
            sisr_model=sisr_model,
            seed=seed,
            log=log,
        )
        rows += level_rows
        search_rows += level_search
    summary = _summary(rows, search_rows, paths, n, (width, height), clean.shape[1:], quick)
    files = {
        "csv": write_csv(out_dir / "noise.csv", rows, CSV_COLUMNS),
        "csv_search": write_csv(out_dir / "noise_deblur_search.csv", search_rows, SEARCH_COLUMNS),
        "png": write_plot(out_dir / "noise.png", _plot(rows)),
        "summary": write_summary(out_dir / "summary.md", summary),
    }
    return ExperimentResult(
        NAME, TITLE, Path(out_dir), rows, files, summary, {"search_rows": search_rows}
    )


def _noise_level(
    sigma: float,
    clip: tuple[np.ndarray, np.ndarray],
    held_out: tuple[np.ndarray, np.ndarray],
    *,
    r: int,
    n: int,
    grid: Any,
    methods: Sequence[str],
    sisr_model: Any,
    seed: int,
    log: Logger,
) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """One noise level of :func:`run_noise`: the deblurring search on the held-out clip, then
    every method on the noisy clip. ``clip`` and ``held_out`` are (clean low-res, truth).

    Returns
    -------
    (rows, search_rows)
    """
    clean, truth = clip
    clean_h, truth_h = held_out
    centre = (n - 1) // 2
    rows: list[dict[str, Any]] = []
    search_rows: list[dict[str, Any]] = []
    sigma = float(sigma)
    lowres = add_laplacian_noise(
        clean, sigma, np.random.default_rng([seed, round(sigma * 1000), 0])
    )
    held = add_laplacian_noise(
        clean_h, sigma, np.random.default_rng([seed, round(sigma * 1000), 1])
    )
    cache: dict[str, Any] = {}

    def fused_video(lowres: np.ndarray = lowres, cache: dict[str, Any] = cache) -> np.ndarray:
        if "fused" not in cache:
            cache["fused"] = super_resolve(lowres, r, n, deblur=False)
        return cache["fused"]  # type: ignore[no-any-return]

    def flows(lowres: np.ndarray = lowres, cache: dict[str, Any] = cache) -> Any:
        if "flows" not in cache:
            cache["flows"] = baselines.upsampled_flows(lowres, r)
        return cache["flows"]

    best: DeblurConfig | None = None
    if "upsr" in methods:
        t0 = time.perf_counter()
        fused_h = super_resolve(held, r, n, deblur=False)[centre]
        best, srows = search_deblur(fused_h, truth_h[centre], r, grid)
        for row in srows:
            search_rows.append({"sigma": sigma, **row})
        log(
            f"sigma {sigma:g}: held-out search -> lam {best.lam:g}, smoothing "
            f"{best.smooth_sigma_mm if best.smooth_sigma_mm is not None else 'off'} "
            f"({time.perf_counter() - t0:.1f} s)"
        )
    runners: dict[str, Callable[[], np.ndarray]] = {
        "nearest": lambda lowres=lowres: baselines.nearest(lowres, r),
        "bicubic": lambda lowres=lowres: baselines.bicubic(lowres, r),
        "bicubic_noflying": lambda lowres=lowres: baselines.bicubic_noflying(lowres, r),
        "shift_add": lambda lowres=lowres: baselines.shift_add(lowres, r, n, flows=flows()),
        "lidarboost": lambda lowres=lowres: baselines.lidarboost(lowres, r, n, flows=flows()),
        "sisr": lambda lowres=lowres: baselines.patch_sisr(lowres, r, model=sisr_model),
        "upsr_fused": fused_video,
        "upsr": lambda best=best: _deblur_video(fused_video(), best, r),  # type: ignore[arg-type]
        "upsr_default": lambda: _deblur_video(fused_video(), DeblurConfig(), r),
    }
    for method in METHODS:
        if method not in methods:
            continue
        t0 = time.perf_counter()
        estimate = runners[method]()
        seconds = time.perf_counter() - t0
        scores = evaluate(estimate, truth, r)
        row: dict[str, Any] = {"method": method, "sigma": sigma}
        row.update({k: float(scores[k]) for k in METRICS})
        if method == "upsr" and best is not None:
            row["deblur_lam"] = best.lam
            row["deblur_smooth_mm"] = (
                best.smooth_sigma_mm if best.smooth_sigma_mm is not None else "off"
            )
        elif method == "upsr_default":
            d = DeblurConfig()
            row["deblur_lam"] = d.lam
            row["deblur_smooth_mm"] = d.smooth_sigma_mm
        row["seconds"] = seconds
        rows.append(row)
        log(f"sigma {sigma:g}: {method:16s} mse {row['mse']:10.1f} mm^2 ({seconds:.1f} s)")
    return rows, search_rows


_COLORS = (*PALETTE, "black", "tab:cyan")


def _plot(rows: list[dict[str, Any]]) -> LinePlot:
    series = []
    for k, method in enumerate(dict.fromkeys(row["method"] for row in rows)):
        mine = [row for row in rows if row["method"] == method]
        style = "dashed" if method in ("upsr", "upsr_default") else "line+markers"
        series.append(
            Series(
                [row["sigma"] for row in mine],
                [row["mse"] for row in mine],
                method,
                _COLORS[k % len(_COLORS)],
                style,  # type: ignore[arg-type]
                3 if method == "upsr" else 2,
            )
        )
    values = [row["mse"] for row in rows if row["mse"] > 0]
    # headroom above the curves (log axis) for the legend
    ylim = (0.8 * min(values), 60.0 * max(values)) if values else None
    return line_plot(
        series,
        title="Samba, r = 4, N = 9: MSE vs noise",
        xlabel="noise σ [mm]",
        ylabel="MSE [mm²]",
        log_y=True,
        ylim=ylim,
        size=(900, 640),
        legend="upper left",
    )


def _summary(
    rows: list[dict[str, Any]],
    search_rows: list[dict[str, Any]],
    paths: Sequence[Path],
    n: int,
    hr: tuple[int, int],
    lr_shape: tuple[int, ...],
    quick: bool,
) -> str:
    methods = list(dict.fromkeys(row["method"] for row in rows))
    sigmas = list(dict.fromkeys(row["sigma"] for row in rows))
    wide = []
    for method in methods:
        entry: dict[str, Any] = {"method": method}
        for row in rows:
            if row["method"] == method:
                entry[f"s{row['sigma']:g}"] = row["mse"]
        wide.append(entry)
    chosen = [
        {
            "sigma": row["sigma"],
            "lam": row["lam"],
            "smooth": row["smooth_sigma_mm"] or "off",
            "mse": row["heldout_mse"],
        }
        for row in search_rows
        if row["chosen"]
    ]
    wins = []
    for sigma in sigmas:
        cands = [row for row in rows if row["sigma"] == sigma]
        wins.append(f"{sigma:g}: {min(cands, key=lambda x: x['mse'])['method']}")
    cols = [f"s{s:g}" for s in sigmas]
    lines = [
        "# MSE vs noise on Samba (paper Fig. 6)",
        "",
        f"Samba {paths[0].name}..{paths[n - 1].name}{' (--quick)' if quick else ''}, input "
        f"{lr_shape[1]}x{lr_shape[0]} -> {hr[0]}x{hr[1]} (r = {SCALE}), N = {n}, Laplacian "
        f"noise; MSE (mm^2) over the pixels valid in truth and output, all {n} output frames "
        "pooled. `upsr`: deblurring parameters chosen per sigma on a held-out frame (centre "
        f"frame of {paths[n].name}..{paths[-1].name}); `upsr_default`: UP-SR's defaults.",
        "",
        markdown_table(
            wide,
            ["method", *cols],
            ["method", *[f"{s:g} mm" for s in sigmas]],
            {c: "{:.1f}" for c in cols},
        ),
        "",
        "Deblurring parameters chosen on the held-out frame:",
        "",
        markdown_table(
            chosen,
            ["sigma", "lam", "smooth", "mse"],
            ["sigma mm", "lambda", "surface smoothing mm", "held-out MSE mm^2"],
            {"sigma": "{:g}", "lam": "{:g}", "mse": "{:.1f}"},
        ),
        "",
        "Lowest MSE per sigma: " + ", ".join(wins) + ".",
        "The other SPEC §6 metrics (rmse, surface rmse, edge accuracy, flying pixels, missing, "
        "invented) are in `noise.csv`.",
    ]
    return "\n".join(lines)
