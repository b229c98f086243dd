"""Small line plots drawn with OpenCV only (no matplotlib): axes, ticks, grid, legend.

:func:`line_plot` draws a few :class:`Series` (solid, dashed or marker-only curves) into a
``uint8`` BGR image that :func:`upsr.viz.colormaps.write_png` writes. It is meant for the
statistical analysis of :mod:`upsr.research.analysis` and for quick diagnostic figures, not for
publication graphics. Text uses OpenCV's Hershey fonts, which know ASCII only.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np
import numpy.typing as npt

from upsr.errors import InputError
from upsr.viz.colormaps import nice_ticks

__all__ = ["PALETTE", "Legend", "Series", "Style", "line_plot"]

#: Distinguishable BGR colours (blue, orange, green, red, purple, brown, grey).
PALETTE: tuple[tuple[int, int, int], ...] = (
    (180, 119, 31),
    (14, 127, 255),
    (44, 160, 44),
    (40, 39, 214),
    (189, 103, 148),
    (75, 86, 140),
    (127, 127, 127),
)

_FONT = cv2.FONT_HERSHEY_SIMPLEX
_AA = cv2.LINE_AA
_BLACK = (0, 0, 0)
_GRID = (225, 225, 225)
_WHITE = (255, 255, 255)

Style = Literal["solid", "dashed", "markers", "line+markers"]
Legend = Literal["upper right", "upper left", "lower right", "lower left"]


@dataclass(frozen=True)
class Series:
    """One curve of a :func:`line_plot`.

    Parameters
    ----------
    x, y : array_like
        Same-length 1-D coordinates. Non-finite points (and, on a log axis, y <= 0) are
        skipped; lines are broken there.
    label : str
        Legend text (ASCII); empty: not in the legend.
    color : tuple of int
        BGR colour.
    style : {"solid", "dashed", "markers", "line+markers"}
        How the points are drawn.
    thickness : int
        Line thickness in pixels.
    """

    x: npt.ArrayLike
    y: npt.ArrayLike
    label: str = ""
    color: tuple[int, int, int] = PALETTE[0]
    style: Style = "solid"
    thickness: int = 2


def _log_ticks(lo: float, hi: float) -> np.ndarray:
    """Ticks at 10^k (and 2·10^k, 5·10^k when the range spans few decades) within [lo, hi]."""
    k0, k1 = math.floor(math.log10(lo)), math.ceil(math.log10(hi))
    mults = (1.0,) if k1 - k0 > 3 else (1.0, 2.0, 5.0)
    ticks = [m * 10.0**k for k in range(k0, k1 + 1) for m in mults]
    t = np.array([v for v in ticks if lo * (1 - 1e-9) <= v <= hi * (1 + 1e-9)])
    return t if t.size >= 2 else np.array([lo, hi])


def _fmt(v: float) -> str:
    if v == 0:
        return "0"
    a = abs(v)
    if a >= 1e5 or a < 1e-3:
        return f"{v:.0e}".replace("e+0", "e").replace("e-0", "e-")
    return f"{v:g}"


def _points(s: Series, log_y: bool) -> tuple[np.ndarray, np.ndarray]:
    x = np.asarray(s.x, dtype=np.float64).ravel()
    y = np.asarray(s.y, dtype=np.float64).ravel()
    if x.shape != y.shape:
        raise InputError(f"series {s.label!r}: x and y differ in length ({x.size} vs {y.size})")
    if s.style not in ("solid", "dashed", "markers", "line+markers"):
        raise InputError(f"series {s.label!r}: unknown style {s.style!r}")
    if log_y:
        with np.errstate(invalid="ignore"):
            y = np.where(y > 0, y, np.nan)
    return x, y


def _padded(lo: float, hi: float, log: bool, frac: float) -> tuple[float, float]:
    """Widen [lo, hi] by ``frac`` of its span on each side (in log space on a log axis)."""
    if log:
        a, b = math.log10(lo), math.log10(hi)
        if b <= a:
            a, b = a - 0.3, b + 0.3
        d = (b - a) * frac
        return 10.0 ** (a - d), 10.0 ** (b + d)
    if hi <= lo:
        d = abs(lo) * 0.1 or 1.0
        return lo - d, hi + d
    d = (hi - lo) * frac
    return lo - d, hi + d


def _dashed(
    img: np.ndarray,
    p: np.ndarray,
    q: np.ndarray,
    color: tuple[int, int, int],
    thickness: int,
    phase: float,
    dash: float = 10.0,
) -> float:
    """Draw p→q dashed (dash/gap of ``dash`` px) starting at ``phase``; return the end phase."""
    length = float(np.hypot(*(q - p)))
    s = 0.0
    while s < length:
        on = int(phase // dash) % 2 == 0
        step = min(dash - phase % dash, length - s)
        if on:
            a = p + (q - p) * (s / length)
            b = p + (q - p) * ((s + step) / length)
            cv2.line(img, _pt(a), _pt(b), color, thickness, _AA)
        s += step
        phase += step
    return phase


def _pt(p: np.ndarray) -> tuple[int, int]:
    return round(float(p[0])), round(float(p[1]))


def _text_size(text: str, scale: float, thickness: int = 1) -> tuple[int, int]:
    (w, h), _ = cv2.getTextSize(text, _FONT, scale, thickness)
    return w, h


def line_plot(
    series: Sequence[Series],
    *,
    title: str = "",
    xlabel: str = "",
    ylabel: str = "",
    size: tuple[int, int] = (800, 520),
    log_y: bool = False,
    xlim: tuple[float, float] | None = None,
    ylim: tuple[float, float] | None = None,
    legend: Legend = "upper right",
) -> np.ndarray:
    """Draw curves on axes with ticks, a grid and a legend; return a uint8 BGR image.

    Parameters
    ----------
    series : sequence of Series
        The curves, drawn in order (later ones on top) and listed in the legend.
    title, xlabel, ylabel : str
        ASCII text (OpenCV's Hershey fonts have no other glyphs).
    size : (int, int)
        Image (width, height) in pixels, at least 240 × 180.
    log_y : bool
        Logarithmic y axis (values <= 0 are not drawn).
    xlim, ylim : (float, float), optional
        Axis ranges; default: the range of the finite data plus a 3 % margin.
    legend : {"upper right", "upper left", "lower right", "lower left"}
        Corner of the legend box, inside the axes.

    Returns
    -------
    ndarray
        (height, width, 3) uint8 BGR image.

    Raises
    ------
    InputError
        No series, no finite point, mismatched x/y, a bad size, style or range.
    """
    if len(series) == 0:
        raise InputError("line_plot needs at least one series")
    width, height = (int(v) for v in size)
    if width < 240 or height < 180:
        raise InputError(f"plot size must be at least 240x180 pixels, got {width}x{height}")
    pts = [_points(s, log_y) for s in series]
    xs = np.concatenate([x[np.isfinite(x) & np.isfinite(y)] for x, y in pts])
    ys = np.concatenate([y[np.isfinite(x) & np.isfinite(y)] for x, y in pts])
    if xs.size == 0:
        raise InputError("line_plot: no finite point to draw")
    x0, x1 = xlim if xlim is not None else (float(xs.min()), float(xs.max()))
    y0, y1 = ylim if ylim is not None else (float(ys.min()), float(ys.max()))
    if not all(math.isfinite(v) for v in (x0, x1, y0, y1)) or x1 < x0 or y1 < y0:
        raise InputError(f"bad axis range x=({x0}, {x1}), y=({y0}, {y1})")
    if log_y and y0 <= 0:
        raise InputError(f"a log y axis needs a positive range, got ({y0}, {y1})")
    if legend not in ("upper right", "upper left", "lower right", "lower left"):
        raise InputError(f"unknown legend position {legend!r}")
    x0, x1 = _padded(x0, x1, False, 0.0 if xlim is not None else 0.03)
    y0, y1 = _padded(y0, y1, log_y, 0.0 if ylim is not None else 0.03)

    img = np.full((height, width, 3), 255, np.uint8)
    fs = 0.45
    yticks = _log_ticks(y0, y1) if log_y else nice_ticks(y0, y1, max(4, height // 80))
    xticks = nice_ticks(x0, x1, max(4, width // 110))
    tick_w = max(_text_size(_fmt(float(t)), fs)[0] for t in yticks)
    left = 18 + (22 if ylabel else 0) + tick_w
    right, top = 20, 40 if title else 16
    bottom = 44 + (20 if xlabel else 0)
    pw, ph = width - left - right, height - top - bottom
    if pw < 60 or ph < 60:
        raise InputError("plot too small for its labels")

    ly0, ly1 = (math.log10(y0), math.log10(y1)) if log_y else (y0, y1)

    def to_px(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        yy = np.log10(y) if log_y else y
        u = left + (x - x0) / (x1 - x0) * pw
        v = top + ph - (yy - ly0) / (ly1 - ly0) * ph
        return np.stack([u, v], axis=-1)

    # grid and ticks
    for t in xticks:
        u = round(left + (t - x0) / (x1 - x0) * pw)
        cv2.line(img, (u, top), (u, top + ph), _GRID, 1)
        cv2.line(img, (u, top + ph), (u, top + ph + 5), _BLACK, 1)
        tw, th = _text_size(_fmt(float(t)), fs)
        org = (u - tw // 2, top + ph + 10 + th)
        cv2.putText(img, _fmt(float(t)), org, _FONT, fs, _BLACK, 1, _AA)
    for t in yticks:
        v = round(top + ph - ((math.log10(t) if log_y else t) - ly0) / (ly1 - ly0) * ph)
        cv2.line(img, (left, v), (left + pw, v), _GRID, 1)
        cv2.line(img, (left - 5, v), (left, v), _BLACK, 1)
        tw, th = _text_size(_fmt(float(t)), fs)
        cv2.putText(img, _fmt(float(t)), (left - 8 - tw, v + th // 2), _FONT, fs, _BLACK, 1, _AA)
    cv2.rectangle(img, (left, top), (left + pw, top + ph), _BLACK, 1)

    # curves, clipped to the plotting area
    area = img[top : top + ph + 1, left : left + pw + 1]
    canvas = area.copy()
    for s, (x, y) in zip(series, pts, strict=True):
        p = to_px(x, y) - np.array([left, top])
        ok = np.isfinite(p).all(axis=1)
        th = max(1, int(s.thickness))
        if s.style in ("solid", "dashed", "line+markers"):
            phase = 0.0
            for i in range(len(p) - 1):
                if ok[i] and ok[i + 1]:
                    if s.style == "dashed":
                        phase = _dashed(canvas, p[i], p[i + 1], s.color, th, phase)
                    else:
                        cv2.line(canvas, _pt(p[i]), _pt(p[i + 1]), s.color, th, _AA)
        if s.style in ("markers", "line+markers"):
            for i in np.flatnonzero(ok):
                cv2.circle(canvas, _pt(p[i]), 3 + th // 2, s.color, -1, _AA)
    area[...] = canvas
    cv2.rectangle(img, (left, top), (left + pw, top + ph), _BLACK, 1)

    # labels
    if title:
        tw, th = _text_size(title, 0.6, 1)
        cv2.putText(img, title, ((width - tw) // 2, 12 + th), _FONT, 0.6, _BLACK, 1, _AA)
    if xlabel:
        tw, th = _text_size(xlabel, 0.5)
        org = (left + (pw - tw) // 2, height - 12)
        cv2.putText(img, xlabel, org, _FONT, 0.5, _BLACK, 1, _AA)
    if ylabel:
        tw, th = _text_size(ylabel, 0.5)
        strip = np.full((th + 8, tw + 4, 3), 255, np.uint8)
        cv2.putText(strip, ylabel, (2, th + 2), _FONT, 0.5, _BLACK, 1, _AA)
        strip = cv2.rotate(strip, cv2.ROTATE_90_COUNTERCLOCKWISE)
        sh, sw = strip.shape[:2]
        r0 = max(0, top + (ph - sh) // 2)
        sh = min(sh, height - r0)
        img[r0 : r0 + sh, 4 : 4 + sw] = strip[:sh]

    # legend (upper right, inside the axes)
    labelled = [s for s in series if s.label]
    if labelled:
        lh = 18
        lw = max(_text_size(s.label, fs)[0] for s in labelled) + 46
        bh = lh * len(labelled) + 8
        bx0 = left + 8 if legend.endswith("left") else left + pw - 8 - lw
        by0 = top + 8 if legend.startswith("upper") else top + ph - 8 - bh
        bx1, by1 = bx0 + lw, by0 + bh
        cv2.rectangle(img, (bx0, by0), (bx1, by1), _WHITE, -1)
        cv2.rectangle(img, (bx0, by0), (bx1, by1), (160, 160, 160), 1)
        for i, s in enumerate(labelled):
            cy = by0 + 4 + lh * i + lh // 2
            a, b = np.array([bx0 + 6.0, cy]), np.array([bx0 + 34.0, cy])
            th = max(1, int(s.thickness))
            if s.style == "dashed":
                _dashed(img, a, b, s.color, th, 0.0, dash=7.0)
            elif s.style != "markers":
                cv2.line(img, _pt(a), _pt(b), s.color, th, _AA)
            if s.style in ("markers", "line+markers"):
                cv2.circle(img, _pt((a + b) / 2), 3 + th // 2, s.color, -1, _AA)
            _, tth = _text_size(s.label, fs)
            cv2.putText(img, s.label, (bx0 + 40, cy + tth // 2), _FONT, fs, _BLACK, 1, _AA)
    return img
