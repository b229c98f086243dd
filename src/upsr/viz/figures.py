"""Line plots for the experiments and the analysis, drawn with matplotlib (PNG and SVG).

:func:`line_plot` checks a few :class:`Series` (solid, dashed or marker-only curves) and the
axes (labels with units and symbols such as σ, mm², log axes, legend) and returns a
:class:`LinePlot`; :func:`write_figure` (or :meth:`LinePlot.save`) draws it with matplotlib's
Agg and SVG backends and writes ``NAME.png`` and ``NAME.svg`` atomically. matplotlib (the
``viz`` extra) is imported only when a figure is drawn, never at import time, and without
pyplot (no global figure state, no display needed).
"""

from __future__ import annotations

import io
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
import numpy.typing as npt

from upsr._atomic import write_bytes_atomic
from upsr.errors import InputError
from upsr.viz._optional import require

__all__ = ["PALETTE", "Legend", "LinePlot", "Series", "Style", "line_plot", "write_figure"]

#: Distinguishable colours (matplotlib's "tab10": blue, orange, green, red, purple, brown, grey).
PALETTE: tuple[str, ...] = (
    "#1f77b4",
    "#ff7f0e",
    "#2ca02c",
    "#d62728",
    "#9467bd",
    "#8c564b",
    "#7f7f7f",
)

Style = Literal["solid", "dashed", "markers", "line+markers"]
Legend = Literal["best", "upper right", "upper left", "lower right", "lower left"]
_STYLES = {"solid": ("-", ""), "dashed": ("--", ""), "markers": ("none", "o")}
_STYLES["line+markers"] = ("-", "o")
_LEGENDS = ("best", "upper right", "upper left", "lower right", "lower left")
_DPI = 100


@dataclass(frozen=True)
class Series:
    """One curve of a :func:`line_plot`.

    Parameters
    ----------
    x, y : array_like
        Same-length 1-D coordinates. Non-finite points (and, on a log axis, values <= 0) are
        skipped; lines are broken there.
    label : str
        Legend text (any Unicode; ``$…$`` is matplotlib mathtext); empty: not in the legend.
    color : str
        A matplotlib colour (``"#1f77b4"``, ``"black"``, ``"tab:cyan"``).
    style : {"solid", "dashed", "markers", "line+markers"}
        How the points are drawn.
    thickness : float
        Line width in points.
    """

    x: npt.ArrayLike
    y: npt.ArrayLike
    label: str = ""
    color: str = PALETTE[0]
    style: Style = "solid"
    thickness: float = 2.0


@dataclass(frozen=True)
class LinePlot:
    """A checked line plot, drawn by :meth:`render` / :meth:`save` (see :func:`line_plot`)."""

    series: tuple[tuple[Series, np.ndarray, np.ndarray], ...]
    title: str
    xlabel: str
    ylabel: str
    size: tuple[int, int]
    log_x: bool
    log_y: bool
    xlim: tuple[float, float] | None
    ylim: tuple[float, float] | None
    legend: Legend

    def figure(self) -> Any:
        """The matplotlib ``Figure`` (no pyplot)."""
        mfig = require("matplotlib.figure", "drawing figures")
        fig = mfig.Figure(figsize=(self.size[0] / _DPI, self.size[1] / _DPI), dpi=_DPI)
        ax = fig.add_subplot()
        for s, x, y in self.series:
            ls, marker = _STYLES[s.style]
            ax.plot(
                x, y, linestyle=ls, marker=marker, markersize=3.0 + s.thickness, color=s.color,
                linewidth=s.thickness, label=s.label or None,
            )  # fmt: skip
        if self.log_x:
            ax.set_xscale("log")
        if self.log_y:
            ax.set_yscale("log")
        if self.xlim is not None:
            ax.set_xlim(*self.xlim)
        if self.ylim is not None:
            ax.set_ylim(*self.ylim)
        ax.set_title(self.title)
        ax.set_xlabel(self.xlabel)
        ax.set_ylabel(self.ylabel)
        ax.grid(True, which="major", color="0.88", linewidth=0.8)
        if self.log_y or self.log_x:
            ax.grid(True, which="minor", color="0.95", linewidth=0.5)
        if any(s.label for s, _, _ in self.series):
            ax.legend(loc=self.legend, framealpha=0.9)
        fig.tight_layout()
        return fig

    def render(self, fmt: Literal["png", "svg"] = "png") -> bytes:
        """The figure as PNG or SVG bytes (SVG text stays text: searchable, selectable)."""
        if fmt not in ("png", "svg"):
            raise InputError(f"figure format must be 'png' or 'svg', got {fmt!r}")
        mpl = require("matplotlib", "drawing figures")
        fig = self.figure()
        buf = io.BytesIO()
        if fmt == "svg":
            with mpl.rc_context({"svg.fonttype": "none", "svg.hashsalt": "upsr"}):
                fig.savefig(buf, format="svg", metadata={"Date": None})
        else:  # opaque RGB (no alpha channel), drawn by Agg
            agg = require("matplotlib.backends.backend_agg", "drawing figures")
            image = require("PIL.Image", "drawing figures")
            canvas = agg.FigureCanvasAgg(fig)
            canvas.draw()
            rgb = np.asarray(canvas.buffer_rgba())[..., :3]
            image.fromarray(np.ascontiguousarray(rgb), "RGB").save(buf, "PNG", optimize=True)
        return buf.getvalue()

    def save(self, path: str | os.PathLike[str]) -> tuple[Path, Path]:
        """Write ``path`` with suffixes ``.png`` and ``.svg``; returns both paths."""
        return write_figure(path, self)


def write_figure(path: str | os.PathLike[str], plot: LinePlot) -> tuple[Path, Path]:
    """Write ``plot`` as ``<path>.png`` and ``<path>.svg`` (suffix of ``path`` replaced),
    each atomically; parent folders are created.

    Returns
    -------
    (pathlib.Path, pathlib.Path)
        The PNG and SVG paths.
    """
    p = Path(path)
    png, svg = p.with_suffix(".png"), p.with_suffix(".svg")
    data = plot.render("png"), plot.render("svg")  # both drawn before anything is written
    return write_bytes_atomic(png, data[0]), write_bytes_atomic(svg, data[1])


def _points(s: Series, log_x: bool, log_y: bool) -> tuple[np.ndarray, np.ndarray]:
    x = np.asarray(s.x, dtype=np.float64).ravel()
    y = np.asarray(s.y, dtype=np.float64).ravel()
    if x.shape != y.shape:
        raise InputError(f"series {s.label!r}: x and y differ in length ({x.size} vs {y.size})")
    if s.style not in _STYLES:
        raise InputError(f"series {s.label!r}: unknown style {s.style!r}")
    if not (math.isfinite(s.thickness) and s.thickness > 0):
        raise InputError(f"series {s.label!r}: thickness must be > 0, got {s.thickness!r}")
    with np.errstate(invalid="ignore"):
        if log_x:
            x = np.where(x > 0, x, np.nan)
        if log_y:
            y = np.where(y > 0, y, np.nan)
    return x, y


def _check_range(lim: tuple[float, float] | None, log: bool, axis: str) -> None:
    if lim is None:
        return
    lo, hi = (float(v) for v in lim)
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi) or (log and lo <= 0):
        raise InputError(f"bad {axis} axis range {lim!r}" + (" (log axis)" if log else ""))


def line_plot(
    series: Sequence[Series],
    *,
    title: str = "",
    xlabel: str = "",
    ylabel: str = "",
    size: tuple[int, int] = (800, 520),
    log_x: bool = False,
    log_y: bool = False,
    xlim: tuple[float, float] | None = None,
    ylim: tuple[float, float] | None = None,
    legend: Legend = "best",
) -> LinePlot:
    """Check curves and axes for a line plot (drawn by :func:`write_figure`).

    Parameters
    ----------
    series : sequence of Series
        The curves, drawn in order (later ones on top) and listed in the legend.
    title, xlabel, ylabel : str
        Text; put units in brackets and use the symbols (``"noise σ [mm]"``, ``"MSE [mm²]"``).
    size : (int, int)
        Figure (width, height) in pixels of the PNG (100 dpi), at least 240 × 180.
    log_x, log_y : bool
        Logarithmic axes (values <= 0 are not drawn).
    xlim, ylim : (float, float), optional
        Axis ranges; default: matplotlib's, around the finite data.
    legend : {"best", "upper right", "upper left", "lower right", "lower left"}
        Where the legend goes, inside the axes.

    Returns
    -------
    LinePlot

    Raises
    ------
    InputError
        No series, no finite point, mismatched x/y, a bad size, style, range or legend.
    """
    if len(series) == 0:
        raise InputError("line_plot needs at least one series")
    width, height = (int(v) for v in size)
    if width < 240 or height < 180:
        raise InputError(f"plot size must be at least 240x180 pixels, got {width}x{height}")
    if legend not in _LEGENDS:
        raise InputError(f"unknown legend position {legend!r}")
    pts = [_points(s, log_x, log_y) for s in series]
    if not any((np.isfinite(x) & np.isfinite(y)).any() for x, y in pts):
        raise InputError("line_plot: no finite point to draw")
    _check_range(xlim, log_x, "x")
    _check_range(ylim, log_y, "y")
    return LinePlot(
        tuple((s, x, y) for s, (x, y) in zip(series, pts, strict=True)),
        title, xlabel, ylabel, (width, height), bool(log_x), bool(log_y),
        None if xlim is None else (float(xlim[0]), float(xlim[1])),
        None if ylim is None else (float(ylim[0]), float(ylim[1])),
        legend,
    )  # fmt: skip
