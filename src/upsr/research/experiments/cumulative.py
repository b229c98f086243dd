"""Cumulative registration (paper §5.2, §7.2, Fig. 2), measured against ground truth.

The paper shows Fig. 2 qualitatively on a real ToF sequence of persons moving fast; here the
fused frame of each registration strategy is scored against the ground truth of a rendered
dynamic sequence: Samba at r = 4 (every 2nd mesh of ``mesh_0000`` … ``mesh_0028``, 15 frames,
input 256×147, truth 1024×588) with a lateral drift of 40 mm per frame added to the dance for
a large motion (≈ 3 low-res px per frame), or :func:`upsr.research.synth.dynamic_scene` with
``--quick``. For each reference
frame t0 (windows of N frames centred on t0) the upsampled frames y_t↑ are registered to t0,
warped by nearest neighbour (:func:`upsr.method.registration.warp_nearest`) and fused by the
invalid-aware temporal median (:func:`upsr.method.fusion.temporal_median`), no deblurring. Only the
motion M_{t0,t} differs:

``none``
    no registration (zero motion): the plain temporal median of the upsampled frames.
``non_cumulative``
    (a) the flow estimated *directly* between the reference and each frame, on the upsampled
    frames.
``cumulative_lowres``
    (b) consecutive flows estimated on the *low-res* frames, upscaled to the high-res grid
    (bilinear resampling of the flow field with the half-pixel geometry of ``SPEC.md`` §1,
    vectors × r) and chained by composition (:func:`upsr.method.registration.cumulative_flows`).
``cumulative_upsampled``
    (c) the proposal: consecutive flows estimated on the *upsampled* frames, chained by
    composition.
``upsr_fused``
    the complete UP-SR fusion (:func:`upsr.super_resolve` with ``deblur=False``): (c) plus the
    eq. 19 re-estimation, spurious-motion suppression and the edge-aware fusion.

(a)–(c) use the same flow backend (UP-SR's default, DIS ``medium``), the same bilateral
prefilter and the same fixed 8-bit mapping (:mod:`upsr.method.motion`), without any of UP-SR's
refinements, so that only the registration strategy changes. Besides the SPEC §6 metrics of
the fused frames, the registration itself is scored: for each frame of the window, the share
of its registered pixels that land on the wrong surface (|registered − truth(t0)| > 100 mm),
as a function of the temporal distance |t − t0|.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Literal

import cv2
import numpy as np

from upsr.method.config import UPSRConfig
from upsr.method.fusion import temporal_median
from upsr.method.motion import (
    FlowBackend,
    bilateral_prefilter,
    depth_range,
    depth_to_u8,
    make_flow_backend,
)
from upsr.method.registration import cumulative_flows, warp_nearest
from upsr.method.upsampling import upsample_nearest
from upsr.method.windowed import super_resolve
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
from upsr.research.synth import add_laplacian_noise, dynamic_scene
from upsr.viz.figures import PALETTE, LinePlot, Series, line_plot

__all__ = [
    "VARIANTS",
    "fuse_with_registration",
    "run_cumulative",
    "upscale_flow",
]

NAME = "cumulative"
TITLE = "Cumulative registration (paper Fig. 2)"
Reference = Literal["centre", "last"]
VARIANTS: tuple[str, ...] = (
    "none",
    "non_cumulative",
    "cumulative_lowres",
    "cumulative_upsampled",
    "upsr_fused",
)
LABELS = {
    "none": "no registration",
    "non_cumulative": "(a) non-cumulative",
    "cumulative_lowres": "(b) cumulative, low-res flows",
    "cumulative_upsampled": "(c) cumulative, upsampled (UP-SR)",
    "upsr_fused": "full UP-SR fusion",
}
METRICS = ("rmse", "mse", "surface_rmse", "edge_accuracy", "flying_pixels", "missing", "invented")
CSV_COLUMNS = ("variant", "sigma", *METRICS, "n_references", "seconds")
DIST_COLUMNS = ("variant", "sigma", "distance", "misregistered", "registered_rmse", "n_pixels")
#: Registered samples further than this from the truth of the reference are misregistered.
MISREGISTERED_MM = 100.0

# Full run: Samba, every `STEP`-th mesh.
SCALE = 4
N_FRAMES = 9
N_TOTAL = 15
STEP = 2
#: Lateral drift added to the dancer (mm per rendered frame), for a large motion as in Fig. 2.
DRIFT_MM = 40.0
HR_SIZE = (1024, 588)
SIGMAS: tuple[float, ...] = (0.0, 10.0, 30.0, 50.0)
# --quick: a synthetic scene
QUICK_SIGMAS: tuple[float, ...] = (0.0, 30.0)
QUICK_SHAPE = (24, 32)
QUICK_N_FRAMES = 5
QUICK_N_TOTAL = 7


def _ref_index(n_frames: int, reference: str) -> int:
    if reference == "centre":
        return (n_frames - 1) // 2
    if reference == "last":
        return n_frames - 1
    raise ValueError(f"reference must be 'centre' or 'last', not {reference!r}")


def upscale_flow(flow: np.ndarray, r: int) -> np.ndarray:
    """A low-res flow field on the r-times finer grid (bilinear, half-pixel geometry, × r)."""
    if r == 1:
        return flow.astype(np.float32, copy=True)
    h, w = flow.shape[:2]
    big = cv2.resize(flow.astype(np.float32), (w * r, h * r), interpolation=cv2.INTER_LINEAR)
    return big * np.float32(r)


class _Motion:
    """Guides and consecutive flows of a whole video, computed once."""

    def __init__(self, lowres: np.ndarray, r: int, backend: FlowBackend) -> None:
        self.r = r
        self.backend = backend
        near, far = depth_range(lowres)
        cfg_hr, cfg_lr = UPSRConfig(scale=r), UPSRConfig(scale=1)
        self.up = [upsample_nearest(f, r) for f in lowres]
        self.guide_hr = [
            depth_to_u8(
                bilateral_prefilter(u, cfg_hr.prefilter_sigma_mm, cfg_hr.spatial_sigma_px),
                near,
                far,
            )
            for u in self.up
        ]
        guide_lr = [
            depth_to_u8(
                bilateral_prefilter(f, cfg_lr.prefilter_sigma_mm, cfg_lr.spatial_sigma_px),
                near,
                far,
            )
            for f in lowres
        ]
        t = len(lowres)
        self.fwd_hr = [backend(self.guide_hr[k], self.guide_hr[k + 1]) for k in range(t - 1)]
        self.bwd_hr = [backend(self.guide_hr[k + 1], self.guide_hr[k]) for k in range(t - 1)]
        self.fwd_lr = [upscale_flow(backend(guide_lr[k], guide_lr[k + 1]), r) for k in range(t - 1)]
        self.bwd_lr = [upscale_flow(backend(guide_lr[k + 1], guide_lr[k]), r) for k in range(t - 1)]

    def maps(self, variant: str, idx: Sequence[int], ref: int) -> list[np.ndarray]:
        shape = self.up[0].shape
        if variant == "none":
            return [np.zeros((*shape, 2), np.float32) for _ in idx]
        if variant == "non_cumulative":
            g0 = self.guide_hr[idx[ref]]
            return [
                np.zeros((*shape, 2), np.float32)
                if j == ref
                else self.backend(g0, self.guide_hr[k])
                for j, k in enumerate(idx)
            ]
        if variant == "cumulative_lowres":
            fwd, bwd = self.fwd_lr, self.bwd_lr
        elif variant == "cumulative_upsampled":
            fwd, bwd = self.fwd_hr, self.bwd_hr
        else:
            raise ValueError(f"unknown variant {variant!r}")
        t = len(self.up)
        return cumulative_flows(
            ref,
            [bwd[k - 1] if k >= 1 else None for k in idx],
            [fwd[k] if k < t - 1 else None for k in idx],
            shape,
        )


def fuse_with_registration(
    lowres: np.ndarray,
    r: int,
    n_frames: int,
    references: Sequence[int],
    variant: str,
    *,
    reference: Reference = "centre",
    motion: Any = None,
) -> tuple[np.ndarray, list[np.ndarray]]:
    """Fuse the window of each reference with one registration strategy (see module docstring).

    Parameters
    ----------
    lowres : ndarray (T, h, w)
        Low-res depth video (mm).
    r : int
        SR factor.
    n_frames : int
        Window length N (reference in the middle).
    references : sequence of int
        Reference frames t0; their windows must lie inside the video.
    variant : str
        One of :data:`VARIANTS` except ``upsr_fused``.
    reference : {"centre", "last"}
        Position of the reference in its window: the middle (as UP-SR) or the end (the
        window t0 − N + 1 … t0 of the paper's data model, §3).
    motion : optional
        Precomputed motion of the video (internal; computed when None).

    Returns
    -------
    fused : ndarray float32 (len(references), r·h, r·w)
    stacks : list of ndarray (N, r·h, r·w)
        The registered frames of each window (NaN outside the frame).
    """
    mot = motion if motion is not None else _Motion(lowres, r, make_flow_backend())
    ref = _ref_index(n_frames, reference)
    fused, stacks = [], []
    for t0 in references:
        s = t0 - ref
        if s < 0 or s + n_frames > len(lowres):
            raise ValueError(f"the window of reference {t0} leaves the video")
        idx = list(range(s, s + n_frames))
        maps = mot.maps(variant, idx, ref)
        stack = np.stack([warp_nearest(mot.up[k], m) for k, m in zip(idx, maps, strict=True)])
        fused.append(temporal_median(stack, ref))
        stacks.append(stack)
    return np.stack(fused), stacks


def _registration_rows(
    variant: str, sigma: float, stacks: list[np.ndarray], truths: np.ndarray, ref: int
) -> list[dict[str, Any]]:
    half = ref
    acc: dict[int, list[float]] = {}
    for stack, truth in zip(stacks, truths, strict=True):
        for j in range(stack.shape[0]):
            d = abs(j - half)
            if d == 0:
                continue
            reg = stack[j]
            both = np.isfinite(reg) & (reg > 0) & (truth > 0)
            err = (reg - truth)[both]
            a = acc.setdefault(d, [0.0, 0.0, 0.0])
            a[0] += float(np.count_nonzero(np.abs(err) > MISREGISTERED_MM))
            a[1] += float(np.sum(err.astype(np.float64) ** 2))
            a[2] += float(err.size)
    return [
        {
            "variant": variant,
            "sigma": sigma,
            "distance": d,
            "misregistered": a[0] / a[2] if a[2] else math.nan,
            "registered_rmse": math.sqrt(a[1] / a[2]) if a[2] else math.nan,
            "n_pixels": int(a[2]),
        }
        for d, a in sorted(acc.items())
    ]


def _load(
    data: str | os.PathLike[str], quick: bool, seed: int, out_dir: Path, log: Logger
) -> tuple[np.ndarray, Any, str]:
    """Clean low-res video, a noisy-video factory, and a description of the data."""
    if quick:
        scene = dynamic_scene(
            n_frames=QUICK_N_TOTAL,
            lowres_shape=QUICK_SHAPE,
            scale=SCALE,
            noise_sigma_mm=0.0,
            background="none",
            seed=seed,
            motion_px=1.5,
        )

        def noisy(sigma: float) -> np.ndarray:
            rng = np.random.default_rng([seed, round(sigma * 1000)])
            return add_laplacian_noise(scene.lowres_clean, sigma, rng)

        desc = (
            "synthetic dynamic scene (upsr.research.synth.dynamic_scene, no background, blob "
            f"moving 1.5 low-res px/frame), {QUICK_SHAPE[1]}x{QUICK_SHAPE[0]} -> "
            f"{QUICK_SHAPE[1] * SCALE}x{QUICK_SHAPE[0] * SCALE}, {QUICK_N_TOTAL} frames"
        )
        return scene.truth, noisy, desc
    paths = samba_mesh_paths(data, 0, N_TOTAL, STEP)
    render = render_samba(
        paths,
        width=HR_SIZE[0],
        height=HR_SIZE[1],
        scales=(SCALE,),
        lateral_mm_per_frame=DRIFT_MM,
        cache_dir=out_dir / "cache",
        log=log,
    )
    clean = render.lowres[SCALE]

    def noisy_samba(sigma: float) -> np.ndarray:
        rng = np.random.default_rng([seed, round(sigma * 1000)])
        return add_laplacian_noise(clean, sigma, rng)

    h, w = clean.shape[1:]
    desc = (
        f"Samba meshes {paths[0].name} ... {paths[-1].name} (mesh stride {STEP}, {N_TOTAL} "
        f"frames) drifting {DRIFT_MM:g} mm/frame to the right, rendered at {w}x{h} (input) "
        f"and {HR_SIZE[0]}x{HR_SIZE[1]} (truth), no background"
    )
    return render.truth, noisy_samba, desc


def _plots(
    rows: list[dict[str, Any]], dist_rows: list[dict[str, Any]], sigma_d: float
) -> tuple[LinePlot, LinePlot]:
    variants = list(dict.fromkeys(row["variant"] for row in rows))
    s1, s2 = [], []
    for k, v in enumerate(variants):
        mine = [row for row in rows if row["variant"] == v]
        color = PALETTE[k % len(PALETTE)]
        s1.append(
            Series(
                [row["sigma"] for row in mine],
                [row["rmse"] for row in mine],
                LABELS[v],
                color,
                "line+markers",
            )
        )
        md = [row for row in dist_rows if row["variant"] == v and row["sigma"] == sigma_d]
        if md:
            s2.append(
                Series(
                    [row["distance"] for row in md],
                    [100.0 * row["misregistered"] for row in md],
                    LABELS[v],
                    color,
                    "line+markers",
                )
            )
    img1 = line_plot(
        s1,
        title="Fused frame error vs noise, by registration strategy",
        xlabel="noise σ [mm]",
        ylabel="RMSE of the fused frame [mm]",
        size=(860, 540),
        legend="upper left",
    )
    img2 = line_plot(
        s2,
        title=f"Registered frames on the wrong surface (σ = {sigma_d:g} mm)",
        xlabel="temporal distance |t − t₀| [frames]",
        ylabel="misregistered pixels [%]",
        size=(860, 540),
        legend="upper left",
    )
    return img1, img2


def run_cumulative(
    out: str | os.PathLike[str] = "results/cumulative",
    data: str | os.PathLike[str] = DEFAULT_DATA,
    *,
    quick: bool = False,
    sigmas: Sequence[float] | None = None,
    reference: Reference = "centre",
    seed: int = 0,
    log: Logger = null_logger,
) -> ExperimentResult:
    """Run the Fig. 2 experiment and write its files into ``out``.

    Files: ``cumulative.csv`` (variant, sigma, SPEC §6 metrics of the fused frames pooled over
    the reference frames), ``cumulative_distance.csv`` (misregistration vs |t − t0|),
    ``cumulative.png`` (fused RMSE vs σ), ``cumulative_distance.png``, ``summary.md``.

    Parameters
    ----------
    out : path-like
        Output folder (created; Samba renders are cached in ``out/cache``).
    data : path-like
        Shared data folder (``samba/mesh_XXXX.obj``); not read with ``quick``.
    quick : bool
        A small synthetic scene, σ = 0 and 30 mm (seconds).
    sigmas : sequence of float, optional
        Noise levels (mm); default 0, 10, 30, 50.
    reference : {"centre", "last"}
        Reference in the middle of its window (as UP-SR) or at its end (paper §3); with
        ``"last"`` the ``upsr_fused`` row (always centred) is left out.
    seed : int
        Noise seed.
    log : callable
        Progress messages.
    """
    out_dir = check_out_dir(out)
    truth, noisy, desc = _load(data, quick, seed, out_dir, log)
    n = QUICK_N_FRAMES if quick else N_FRAMES
    ref = _ref_index(n, reference)
    references = list(range(ref, truth.shape[0] - (n - 1 - ref)))
    variants = [v for v in VARIANTS if reference == "centre" or v != "upsr_fused"]
    sig = tuple(sigmas) if sigmas is not None else (QUICK_SIGMAS if quick else SIGMAS)
    log(f"{desc}; N = {n}, references {references[0]}..{references[-1]}")
    rows: list[dict[str, Any]] = []
    dist_rows: list[dict[str, Any]] = []
    truths = truth[references]
    for sigma in sig:
        lowres = noisy(float(sigma))
        t0 = time.perf_counter()
        motion = _Motion(lowres, SCALE, make_flow_backend())
        log(f"sigma {sigma:g}: consecutive flows ({time.perf_counter() - t0:.1f} s)")
        for variant in variants:
            t1 = time.perf_counter()
            if variant == "upsr_fused":
                fused = super_resolve(lowres, SCALE, n, deblur=False)[references]
                stacks = None
            else:
                fused, stacks = fuse_with_registration(
                    lowres, SCALE, n, references, variant, reference=reference, motion=motion
                )
            seconds = time.perf_counter() - t1
            scores = evaluate(fused, truths, SCALE)
            row: dict[str, Any] = {"variant": variant, "sigma": float(sigma)}
            row.update({k: float(scores[k]) for k in METRICS})
            row["n_references"] = len(references)
            row["seconds"] = seconds
            rows.append(row)
            if stacks is not None:
                dist_rows.extend(_registration_rows(variant, float(sigma), stacks, truths, ref))
            log(f"sigma {sigma:g}: {variant:22s} rmse {row['rmse']:.2f} mm ({seconds:.1f} s)")
    sigma_d = float(sig[0])
    img1, img2 = _plots(rows, dist_rows, sigma_d)
    summary = _summary(rows, dist_rows, desc, n, references, sigma_d, reference)
    files = {
        "csv": write_csv(out_dir / "cumulative.csv", rows, CSV_COLUMNS),
        "csv_distance": write_csv(out_dir / "cumulative_distance.csv", dist_rows, DIST_COLUMNS),
        "png": write_plot(out_dir / "cumulative.png", img1),
        "png_distance": write_plot(out_dir / "cumulative_distance.png", img2),
        "summary": write_summary(out_dir / "summary.md", summary),
    }
    return ExperimentResult(
        NAME, TITLE, out_dir, rows, files, summary, {"distance_rows": dist_rows}
    )


def _summary(
    rows: list[dict[str, Any]],
    dist_rows: list[dict[str, Any]],
    desc: str,
    n: int,
    references: list[int],
    sigma_d: float,
    reference: str,
) -> str:
    table_rows = [{**row, "label": LABELS[row["variant"]]} for row in rows]
    for row in table_rows:
        for k in ("edge_accuracy", "flying_pixels", "missing", "invented"):
            row[k + "_pct"] = 100.0 * row[k]
    dist_wide = []
    dmax = max((row["distance"] for row in dist_rows), default=0)
    for v in VARIANTS:
        mine = {
            row["distance"]: row
            for row in dist_rows
            if row["variant"] == v and row["sigma"] == sigma_d
        }
        if mine:
            entry: dict[str, Any] = {"label": LABELS[v]}
            for d in range(1, dmax + 1):
                entry[f"d{d}"] = 100.0 * mine[d]["misregistered"] if d in mine else math.nan
            dist_wide.append(entry)
    best = {}
    for sigma in dict.fromkeys(row["sigma"] for row in rows):
        cands = [row for row in rows if row["sigma"] == sigma and row["variant"] != "upsr_fused"]
        best[sigma] = min(cands, key=lambda x: x["rmse"])["variant"]
    lines = [
        "# Cumulative registration (paper Fig. 2)",
        "",
        f"Data: {desc}. r = {SCALE}, N = {n}, reference "
        + ("in the middle of" if reference == "centre" else "at the end of")
        + f" its window, references {references[0]}..{references[-1]} (metrics pooled over "
        "them). Fused frames (temporal "
        "median, no deblurring); (a)-(c) share the flow backend (DIS medium), prefilter and "
        "8-bit mapping and differ only in how the motion to the reference is obtained.",
        "",
        markdown_table(
            table_rows,
            [
                "label",
                "sigma",
                "rmse",
                "surface_rmse",
                "edge_accuracy_pct",
                "flying_pixels_pct",
                "missing_pct",
            ],
            [
                "registration",
                "sigma mm",
                "rmse mm",
                "surface rmse mm",
                "edge acc. %",
                "flying %",
                "missing %",
            ],
            {
                "sigma": "{:g}",
                "rmse": "{:.2f}",
                "surface_rmse": "{:.2f}",
                "edge_accuracy_pct": "{:.2f}",
                "flying_pixels_pct": "{:.2f}",
                "missing_pct": "{:.2f}",
            },
        ),
        "",
        f"Registered frames on the wrong surface (|registered - truth| > {MISREGISTERED_MM:g} mm, "
        f"% of pixels), sigma = {sigma_d:g} mm, by temporal distance to the reference:",
        "",
        markdown_table(
            dist_wide,
            ["label", *[f"d{d}" for d in range(1, dmax + 1)]],
            ["registration", *[f"d = {d}" for d in range(1, dmax + 1)]],
            {f"d{d}": "{:.2f}" for d in range(1, dmax + 1)},
        ),
        "",
        "Lowest fused RMSE among (none, a, b, c) per sigma: "
        + ", ".join(f"{s:g} mm: {LABELS[v]}" for s, v in best.items())
        + ".",
    ]
    return "\n".join(lines)
