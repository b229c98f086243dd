"""The two figures of :func:`upsr.research.analysis.run_analysis` (matplotlib, PNG + SVG)."""

from __future__ import annotations

from typing import Any

import numpy as np

from upsr.viz.figures import PALETTE, LinePlot, Series, line_plot

__all__ = ["analysis_plots"]


def analysis_plots(
    vs_n: list[dict[str, Any]],
    vs_sigma: list[dict[str, Any]],
    s: float,
    n_trials: int,
    n_vs_sigma: int,
) -> tuple[LinePlot, LinePlot]:
    """The figures of :func:`upsr.research.analysis.run_analysis`: variance vs N (log axis, at
    σ = ``s`` mm) and vs σ (at N = ``n_vs_sigma``), from the rows of its two sweeps."""
    col = {k: np.array([row[k] for row in vs_n]) for k in vs_n[0]}
    cs = {k: np.array([row[k] for row in vs_sigma]) for k in vs_sigma[0]}
    ns, sig = col["n_frames"], cs["sigma_mm"]
    size = (820, 540)
    mc_label = f"Monte-Carlo ({n_trials} trials)"
    crb_label = "Cramér–Rao bound σ²/(2N)"
    plot_n = line_plot(
        [
            Series(ns, col["paper_printed_mm2"], "paper eq. (35)–(37) as printed", PALETTE[3],
                   "dashed"),
            Series(ns, col["crb_mm2"], crb_label, PALETTE[2], "dashed"),
            Series(ns, col["variance_mm2"], "exact variance (theory)", PALETTE[0], "solid"),
            Series(ns, col["mc_variance_mm2"], mc_label, PALETTE[1], "markers"),
        ],
        title=f"Median of N Laplace samples, σ = {s:g} mm",
        xlabel="number of frames N",
        ylabel="variance of the median [mm²]",
        size=size,
        log_y=True,
        legend="upper right",
    )  # fmt: skip
    plot_s = line_plot(
        [
            Series(sig, cs["crb_mm2"], crb_label, PALETTE[2], "dashed"),
            Series(sig, cs["variance_mm2"], "exact variance (theory)", PALETTE[0], "solid"),
            Series(sig, cs["mc_variance_mm2"], mc_label, PALETTE[1], "markers"),
        ],
        title=f"Median of N = {n_vs_sigma} Laplace samples",
        xlabel="noise standard deviation σ [mm]",
        ylabel="variance of the median [mm²]",
        size=size,
        legend="upper left",
    )
    return plot_n, plot_s
