"""Pictures of depth maps with OpenCV only: colour maps, colour bars, panel grids, PNG files.

All images are ``uint8`` BGR (OpenCV's channel order), shape (h, w, 3). Invalid depth (0 or
NaN, "no measurement") is drawn in a flat colour that no colour map used here produces:
black, :data:`INVALID_BGR` (the darkest colours of TURBO and VIRIDIS are dark blue/purple).
Text is drawn with OpenCV's Hershey fonts, which know ASCII only.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt

from upsr._atomic import write_bytes_atomic
from upsr.errors import InputError

__all__ = [
    "INVALID_BGR",
    "colorbar",
    "colorize_depth",
    "colorize_error",
    "nice_ticks",
    "panel_grid",
    "write_png",
]

#: Colour (B, G, R) of pixels without a value.
INVALID_BGR: tuple[int, int, int] = (0, 0, 0)

_FONT = cv2.FONT_HERSHEY_SIMPLEX


def _as_map(a: npt.ArrayLike, name: str) -> np.ndarray:
    arr = np.asarray(a)
    if arr.dtype == object or not (
        np.issubdtype(arr.dtype, np.integer) or np.issubdtype(arr.dtype, np.floating)
    ):
        raise InputError(f"{name} must be a numeric array, got dtype {arr.dtype}")
    if arr.ndim != 2 or arr.size == 0:
        raise InputError(f"{name} must be a non-empty 2-D array (h, w), got shape {arr.shape}")
    return arr.astype(np.float64)


def _check_range(vmin: float, vmax: float) -> tuple[float, float]:
    vmin, vmax = float(vmin), float(vmax)
    if not (math.isfinite(vmin) and math.isfinite(vmax) and vmax > vmin):
        raise InputError(f"need finite vmin < vmax, got vmin={vmin!r}, vmax={vmax!r}")
    return vmin, vmax


def _apply_colormap(values01: np.ndarray, colormap: int) -> np.ndarray:
    """Map values in [0, 1] (h, w) to BGR uint8 through an OpenCV colour map."""
    idx = np.round(np.clip(values01, 0.0, 1.0) * 255).astype(np.uint8)
    return cv2.applyColorMap(idx, colormap)


def colorize_depth(
    depth_mm: npt.ArrayLike,
    vmin_mm: float | None = None,
    vmax_mm: float | None = None,
    colormap: int = cv2.COLORMAP_TURBO,
    *,
    invalid_bgr: tuple[int, int, int] = INVALID_BGR,
) -> np.ndarray:
    """Colour-code a depth map.

    Parameters
    ----------
    depth_mm : array_like, shape (h, w)
        Depth in mm; 0 or NaN = invalid.
    vmin_mm, vmax_mm : float or None
        Depths mapped to the two ends of the colour map (values outside are clipped). ``None``:
        the 1st / 99th percentile of the valid depths.
    colormap : int
        An OpenCV colour map (``cv2.COLORMAP_*``); TURBO: near = blue, far = red.
    invalid_bgr : (int, int, int)
        Flat colour of invalid pixels (default black).

    Returns
    -------
    ndarray of uint8, shape (h, w, 3), BGR.
    """
    d = _as_map(depth_mm, "depth_mm")
    valid = np.isfinite(d) & (d > 0)
    if vmin_mm is None or vmax_mm is None:
        vals = d[valid]
        lo, hi = np.percentile(vals, [1, 99]) if vals.size else (0.0, 1.0)
        vmin_mm = lo if vmin_mm is None else vmin_mm
        vmax_mm = hi if vmax_mm is None else vmax_mm
        if vmax_mm <= vmin_mm:
            vmax_mm = vmin_mm + 1.0
    vmin, vmax = _check_range(vmin_mm, vmax_mm)
    img = _apply_colormap(np.where(valid, (d - vmin) / (vmax - vmin), 0.0), colormap)
    img[~valid] = invalid_bgr
    return img


def colorize_error(
    err_mm: npt.ArrayLike,
    max_mm: float,
    colormap: int = cv2.COLORMAP_VIRIDIS,
    *,
    invalid_bgr: tuple[int, int, int] = INVALID_BGR,
) -> np.ndarray:
    """Colour-code an error map: |err| from 0 (dark purple) to ``max_mm`` and more (yellow).

    Parameters
    ----------
    err_mm : array_like, shape (h, w)
        Error in mm (its magnitude is shown); NaN = no value (e.g. missing output or truth).
    max_mm : float
        Error (mm) at the top of the colour map; larger errors are clipped.
    colormap : int
        OpenCV colour map (default VIRIDIS, which never reaches black).
    invalid_bgr : (int, int, int)
        Flat colour of NaN pixels (default black).

    Returns
    -------
    ndarray of uint8, shape (h, w, 3), BGR.
    """
    e = _as_map(err_mm, "err_mm")
    _, max_mm = _check_range(0.0, max_mm)
    valid = np.isfinite(e)
    img = _apply_colormap(np.where(valid, np.abs(e) / max_mm, 0.0), colormap)
    img[~valid] = invalid_bgr
    return img


def nice_ticks(vmin: float, vmax: float, n: int = 5) -> np.ndarray:
    """About ``n`` round tick values (steps of 1, 2, 2.5 or 5 × 10^k) within [vmin, vmax]."""
    vmin, vmax = _check_range(vmin, vmax)
    raw = (vmax - vmin) / max(n - 1, 1)
    mag = 10.0 ** math.floor(math.log10(raw))
    step = next(s * mag for s in (1.0, 2.0, 2.5, 5.0, 10.0) if s * mag >= raw)
    start = math.ceil(vmin / step - 1e-9) * step
    ticks = np.arange(start, vmax + step * 1e-9, step)
    return ticks[(ticks >= vmin - 1e-9 * step) & (ticks <= vmax + 1e-9 * step)]


def _fmt_tick(v: float) -> str:
    return f"{v:g}" if abs(v) < 1e6 else f"{v:.3g}"


def colorbar(
    height_px: int,
    vmin: float,
    vmax: float,
    label: str = "mm",
    *,
    colormap: int = cv2.COLORMAP_TURBO,
    bar_width_px: int = 18,
    n_ticks: int = 5,
    background_bgr: tuple[int, int, int] = (255, 255, 255),
    text_bgr: tuple[int, int, int] = (0, 0, 0),
    font_scale: float = 0.45,
) -> np.ndarray:
    """A vertical colour bar (``vmax`` at the top) with tick labels and a unit label above.

    Parameters
    ----------
    height_px : int
        Total image height (px), at least 40.
    vmin, vmax : float
        Values at the bottom and top of the bar (same units as the colour-coded map).
    label : str
        Unit / title written above the bar (ASCII).
    colormap : int
        OpenCV colour map, the one used for the map it explains.

    Returns
    -------
    ndarray of uint8, shape (height_px, width, 3), BGR.
    """
    if (
        isinstance(height_px, bool)
        or not isinstance(height_px, (int, np.integer))
        or height_px < 40
    ):
        raise InputError(f"height_px must be an integer >= 40, got {height_px!r}")
    vmin, vmax = _check_range(vmin, vmax)
    ticks = nice_ticks(vmin, vmax, n_ticks)
    labels = [_fmt_tick(float(t)) for t in ticks]
    thickness = 1
    (_, text_h), _ = cv2.getTextSize("0", _FONT, font_scale, thickness)
    label_w = max(
        [cv2.getTextSize(s, _FONT, font_scale, thickness)[0][0] for s in labels]
        + [cv2.getTextSize(label, _FONT, font_scale, thickness)[0][0] - bar_width_px]
    )
    pad = 4
    width = pad + bar_width_px + 4 + label_w + pad
    top = text_h + 2 * pad + 2
    bottom = height_px - max(text_h // 2 + 2, pad)
    img = np.empty((height_px, width, 3), np.uint8)
    img[:] = background_bgr
    rows = bottom - top
    grad = 1.0 - (np.arange(rows) + 0.5) / rows  # top row = vmax
    bar = _apply_colormap(np.repeat(grad[:, None], bar_width_px, axis=1), colormap)
    img[top:bottom, pad : pad + bar_width_px] = bar
    cv2.rectangle(img, (pad - 1, top - 1), (pad + bar_width_px, bottom), text_bgr, 1)
    cv2.putText(
        img, label, (pad, text_h + pad), _FONT, font_scale, text_bgr, thickness, cv2.LINE_AA
    )
    x_tick = pad + bar_width_px
    for t, s in zip(ticks, labels, strict=True):
        y = int(np.rint(bottom - (t - vmin) / (vmax - vmin) * rows))
        y = min(max(y, top), bottom - 1)
        cv2.line(img, (x_tick, y), (x_tick + 3, y), text_bgr, 1)
        cv2.putText(
            img,
            s,
            (x_tick + 5, y + text_h // 2),
            _FONT,
            font_scale,
            text_bgr,
            thickness,
            cv2.LINE_AA,
        )
    return img


def _as_bgr(image: npt.ArrayLike, name: str) -> np.ndarray:
    img = np.asarray(image)
    if img.dtype != np.uint8:
        raise InputError(f"{name}: expected a uint8 image, got dtype {img.dtype}")
    if img.ndim == 2:
        return cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    if img.ndim == 3 and img.shape[2] == 3 and img.shape[0] > 0 and img.shape[1] > 0:
        return img
    raise InputError(f"{name}: expected an (h, w) or (h, w, 3) image, got shape {img.shape}")


def _fit_text(text: str, max_width: int, font_scale: float) -> float:
    width = cv2.getTextSize(text, _FONT, font_scale, 1)[0][0]
    if width > max_width > 0:
        font_scale *= max_width / width
    return max(font_scale, 0.25)


def panel_grid(
    panels: Sequence[tuple[str, npt.ArrayLike]],
    *,
    ncols: int | None = None,
    min_height_px: int = 0,
    title_height_px: int = 24,
    gap_px: int = 6,
    background_bgr: tuple[int, int, int] = (255, 255, 255),
    text_bgr: tuple[int, int, int] = (0, 0, 0),
    font_scale: float = 0.5,
) -> np.ndarray:
    """Lay titled images out side by side (one row, or rows of ``ncols``).

    Every panel is enlarged by the largest integer factor k with k·h ≤ the target height (the
    tallest panel, at least ``min_height_px``), with nearest-neighbour replication: a low-res
    image shows its pixels as blocks and nothing is interpolated. Panels are then centred
    vertically in their row. An empty title leaves the title strip blank.

    Parameters
    ----------
    panels : sequence of (str, ndarray)
        (title, image) pairs; images are uint8 BGR (h, w, 3) or grey (h, w).
    ncols : int or None
        Panels per row; ``None``: all in one row.
    min_height_px : int
        Enlarge panels (by integer factors) to at least about this height.

    Returns
    -------
    ndarray of uint8, BGR.
    """
    if len(panels) == 0:
        raise InputError("panel_grid needs at least one (title, image) panel")
    images = []
    for i, item in enumerate(panels):
        if not (isinstance(item, (tuple, list)) and len(item) == 2):
            raise InputError(f"panel {i}: expected a (title, image) pair")
        images.append((str(item[0]), _as_bgr(item[1], f"panel {i} ({item[0]!r})")))
    target = max(max(img.shape[0] for _, img in images), int(min_height_px))
    scaled = []
    for title, img in images:
        k = max(1, target // img.shape[0])
        if k > 1:
            img = cv2.resize(
                img, (img.shape[1] * k, img.shape[0] * k), interpolation=cv2.INTER_NEAREST
            )
        scaled.append((title, img))
    ncols = len(scaled) if ncols is None else int(ncols)
    if ncols < 1:
        raise InputError(f"ncols must be >= 1, got {ncols}")
    rows = [scaled[i : i + ncols] for i in range(0, len(scaled), ncols)]
    row_images = []
    for row in rows:
        h = max(img.shape[0] for _, img in row)
        cells = []
        for title, img in row:
            body = np.empty((h, img.shape[1], 3), np.uint8)
            body[:] = background_bgr
            y0 = (h - img.shape[0]) // 2
            body[y0 : y0 + img.shape[0]] = img
            strip = np.empty((title_height_px, img.shape[1], 3), np.uint8)
            strip[:] = background_bgr
            if title:
                fs = _fit_text(title, img.shape[1] - 4, font_scale)
                (tw, th), base = cv2.getTextSize(title, _FONT, fs, 1)
                org = (
                    max((img.shape[1] - tw) // 2, 0),
                    max((title_height_px - th - base) // 2, 0) + th,
                )
                cv2.putText(strip, title, org, _FONT, fs, text_bgr, 1, cv2.LINE_AA)
            cells.append(np.vstack([strip, body]))
        row_images.append(_hstack(cells, gap_px, background_bgr))
    width = max(r.shape[1] for r in row_images)
    padded = []
    for r in row_images:
        if r.shape[1] < width:
            extra = np.empty((r.shape[0], width - r.shape[1], 3), np.uint8)
            extra[:] = background_bgr
            r = np.hstack([r, extra])
        padded.append(r)
    return _vstack(padded, gap_px, background_bgr)


def _hstack(cells: list[np.ndarray], gap: int, bg: tuple[int, int, int]) -> np.ndarray:
    out = []
    for i, c in enumerate(cells):
        if i:
            g = np.empty((c.shape[0], gap, 3), np.uint8)
            g[:] = bg
            out.append(g)
        out.append(c)
    return np.hstack(out)


def _vstack(rows: list[np.ndarray], gap: int, bg: tuple[int, int, int]) -> np.ndarray:
    out = []
    for i, r in enumerate(rows):
        if i:
            g = np.empty((gap, r.shape[1], 3), np.uint8)
            g[:] = bg
            out.append(g)
        out.append(r)
    return np.vstack(out)


def write_png(path: str | os.PathLike[str], image: npt.ArrayLike) -> Path:
    """Write ``image`` as a PNG atomically (temporary file in the same folder, then rename).

    A reader never sees a half-written file, and an existing file is replaced only when the
    new one is complete. Missing parent folders are created.

    Parameters
    ----------
    path : str or path-like
        Destination (``.png``).
    image : ndarray
        uint8 or uint16, (h, w) grey, (h, w, 3) BGR or (h, w, 4) BGRA.

    Returns
    -------
    pathlib.Path
        The path written.
    """
    img = np.asarray(image)
    if img.dtype not in (np.uint8, np.uint16):
        raise InputError(f"PNG images must be uint8 or uint16, got dtype {img.dtype}")
    if not (img.ndim == 2 or (img.ndim == 3 and img.shape[2] in (1, 3, 4))) or img.size == 0:
        raise InputError(f"expected an (h, w), (h, w, 3) or (h, w, 4) image, got {img.shape}")
    ok, buf = cv2.imencode(".png", np.ascontiguousarray(img))
    if not ok:  # pragma: no cover - OpenCV refuses only unsupported layouts, checked above
        raise InputError(f"OpenCV could not encode an image of shape {img.shape} as PNG")
    return write_bytes_atomic(path, buf.tobytes())
