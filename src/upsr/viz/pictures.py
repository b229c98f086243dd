"""Pictures of results: side-by-side comparisons (PNG / GIF / MP4) and 3-D views of a frame.

:func:`comparison_frame` lays out, for one frame, the low-res input (its pixels shown as
blocks), bicubic interpolation, UP-SR, and optionally the ground truth and the error map
|UP-SR − truth|, with colour bars in mm. Every depth panel shares one colour scale (TURBO, near
= blue); pixels without depth are black in every panel (no colour of the maps is black), and
in the error map a pixel where the output or the truth has no depth is black too.
:class:`ComparisonWriter` streams such frames into a PNG (one frame), an animated GIF
or an H.264 MP4 (both :mod:`upsr.viz.animation`), atomically.

:func:`render_view` renders a depth frame as a shaded 3-D surface seen from a rotated viewpoint
(like Fig. 3 of the paper): the pixels become a triangle mesh (no triangle spans a depth jump
larger than ``edge_mm``, so foreground and background stay apart), rendered with the z-buffer
rasteriser of :mod:`upsr.geometry.rendering` and lit from the viewer.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from upsr._atomic import AtomicWriter
from upsr.errors import InputError
from upsr.geometry.camera import PinholeCamera
from upsr.geometry.rendering import look_at, render_depth
from upsr.method.upsampling import upsample_bicubic
from upsr.method.validation import as_depth_frame
from upsr.viz.colormaps import colorbar, colorize_depth, colorize_error, panel_grid, write_png

__all__ = [
    "ComparisonWriter",
    "comparison_frame",
    "depth_mesh",
    "picture_kind",
    "render_view",
]

_FONT = cv2.FONT_HERSHEY_SIMPLEX


def picture_kind(path: str | os.PathLike[str]) -> str:
    """ "png", "gif" or "mp4" from the suffix of ``path`` (InputError otherwise)."""
    suffix = Path(path).suffix.lower()
    kinds = {".png": "png", ".gif": "gif", ".mp4": "mp4"}
    if suffix not in kinds:
        raise InputError(f"{path}: the picture must be a .png, .gif or .mp4 file")
    return kinds[suffix]


def _pad_height(img: np.ndarray, h: int) -> np.ndarray:
    if img.shape[0] >= h:
        return img
    pad = np.full((h - img.shape[0], img.shape[1], 3), 255, np.uint8)
    return np.vstack([img, pad])


def _hcat(images: list[np.ndarray], gap: int = 6) -> np.ndarray:
    h = max(i.shape[0] for i in images)
    out: list[np.ndarray] = []
    for k, img in enumerate(images):
        if k:
            out.append(np.full((h, gap, 3), 255, np.uint8))
        out.append(_pad_height(img, h))
    return np.hstack(out)


def _caption(width: int, text: str) -> np.ndarray:
    strip = np.full((22, width, 3), 255, np.uint8)
    cv2.putText(strip, text, (6, 16), _FONT, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
    return strip


def comparison_frame(
    lowres_mm: npt.ArrayLike,
    upsr_mm: npt.ArrayLike,
    scale: int,
    truth_mm: npt.ArrayLike | None = None,
    *,
    vmin_mm: float,
    vmax_mm: float,
    error_max_mm: float | None = None,
    caption: str = "",
) -> np.ndarray:
    """One side-by-side picture (BGR uint8) of a frame.

    Parameters
    ----------
    lowres_mm : array_like (h, w)
        Low-res input depth (mm, 0 = none).
    upsr_mm : array_like (r·h, r·w)
        UP-SR output (mm).
    scale : int
        r.
    truth_mm : array_like (r·h, r·w), optional
        Ground truth (mm): adds the truth and |UP-SR − truth| panels.
    vmin_mm, vmax_mm : float
        Depth colour scale (shared by all depth panels and frames of an animation).
    error_max_mm : float, optional
        Top of the error colour scale (default: 99th percentile of this frame's errors).
    caption : str
        ASCII text under the panels (e.g. the frame number).
    """

    low = as_depth_frame(lowres_mm, name="low-res frame")
    up = as_depth_frame(upsr_mm, name="UP-SR frame")
    r = int(scale)
    if up.shape != (low.shape[0] * r, low.shape[1] * r):
        raise InputError(
            f"UP-SR frame {up.shape[1]}x{up.shape[0]} is not r={r} times the low-res "
            f"{low.shape[1]}x{low.shape[0]}"
        )
    bic = upsample_bicubic(low[None], r)[0]
    panels: list[tuple[str, np.ndarray]] = [
        ("low-res", colorize_depth(low, vmin_mm, vmax_mm)),
        ("bicubic", colorize_depth(bic, vmin_mm, vmax_mm)),
        ("UP-SR", colorize_depth(up, vmin_mm, vmax_mm)),
    ]
    err_img = None
    if truth_mm is not None:
        truth = as_depth_frame(truth_mm, name="truth frame")
        if truth.shape != up.shape:
            raise InputError(f"truth frame {truth.shape} differs from the UP-SR frame {up.shape}")
        both = (truth > 0) & (up > 0)
        err = np.where(both, up - truth, np.nan)
        if error_max_mm is None:
            vals = np.abs(err[both])
            error_max_mm = max(float(np.percentile(vals, 99)), 1.0) if vals.size else 1.0
        panels.append(("truth", colorize_depth(truth, vmin_mm, vmax_mm)))
        panels.append(("|UP-SR - truth|", colorize_error(err, error_max_mm)))
        err_img = True
    grid = panel_grid(panels, min_height_px=240)
    bars = [colorbar(grid.shape[0], vmin_mm, vmax_mm, "mm")]
    if err_img:
        assert error_max_mm is not None
        bars.append(
            colorbar(grid.shape[0], 0.0, error_max_mm, "err mm", colormap=cv2.COLORMAP_VIRIDIS)
        )
    body = _hcat([grid, *bars])
    text = "black: no depth" + (f"   {caption}" if caption else "")
    return np.vstack([body, _caption(body.shape[1], text)])


class ComparisonWriter(AtomicWriter):
    """Write comparison pictures to ``.png`` (one frame), ``.gif`` or ``.mp4``, atomically.

    Parameters
    ----------
    path : path-like
        Destination; its suffix chooses the kind.
    fps : float
        Frame rate of animations.
    """

    def __init__(self, path: str | os.PathLike[str], fps: float = 5.0) -> None:
        self.path = Path(path)
        self.kind = picture_kind(self.path)
        if not (math.isfinite(fps) and fps > 0):
            raise InputError(f"fps must be > 0, got {fps!r}")
        self.fps = float(fps)
        self._impl: Any = None
        self.frames_written = 0

    def write(self, image_bgr: np.ndarray) -> None:
        """Add one picture (BGR uint8); a PNG takes exactly one."""
        if self.kind == "png":
            if self.frames_written:
                raise InputError(f"{self.path}: a PNG holds one picture (use .gif or .mp4)")
            self._impl = image_bgr
        else:
            if self._impl is None:
                from upsr.viz.animation import GifWriter, Mp4Writer

                kind = GifWriter if self.kind == "gif" else Mp4Writer
                self._impl = kind(self.path, fps=self.fps)
            self._impl.write(image_bgr)
        self.frames_written += 1

    def close(self) -> Path:
        """Finish and move the picture into place."""
        if self.frames_written == 0:
            raise InputError(f"{self.path}: no frames to write")
        if self.kind == "png":
            write_png(self.path, self._impl)
        else:
            self._impl.close()
        self._impl = None
        return self.path

    def abort(self) -> None:
        """Discard everything written."""
        if self.kind != "png" and self._impl is not None:
            self._impl.abort()
        self._impl = None


# ---------------------------------------------------------------------------------------------
# 3-D view
# ---------------------------------------------------------------------------------------------
def depth_mesh(
    depth_mm: npt.ArrayLike, camera: PinholeCamera, edge_mm: float = 100.0
) -> tuple[np.ndarray, np.ndarray]:
    """Triangle mesh of a depth frame: one vertex per pixel (metres), two triangles per 2×2
    block of valid pixels whose depths span at most ``edge_mm``.

    Returns
    -------
    vertices : ndarray float64 (h·w, 3)
        Back-projected pixel centres (camera frame, metres; invalid pixels at the origin,
        unused).
    faces : ndarray int64 (F, 3)
    """
    d = as_depth_frame(depth_mm, name="depth")
    if d.shape != camera.shape:
        raise InputError(
            f"intrinsics are for {camera.width}x{camera.height} images, the frame is "
            f"{d.shape[1]}x{d.shape[0]}"
        )
    h, w = d.shape
    z = d.astype(np.float64) / 1000.0
    xs, ys = camera.rays()
    verts = np.stack([xs * z, ys * z, z], axis=-1).reshape(-1, 3)
    idx = np.arange(h * w).reshape(h, w)
    a, b, c, e = idx[:-1, :-1], idx[:-1, 1:], idx[1:, :-1], idx[1:, 1:]
    za, zb, zc, ze = d[:-1, :-1], d[:-1, 1:], d[1:, :-1], d[1:, 1:]
    faces = []
    for (p, q, s), (zp, zq, zs) in (((a, b, c), (za, zb, zc)), ((b, e, c), (zb, ze, zc))):
        lo = np.minimum(np.minimum(zp, zq), zs)
        hi = np.maximum(np.maximum(zp, zq), zs)
        ok = (lo > 0) & (hi - lo <= edge_mm)
        faces.append(np.stack([p[ok], q[ok], s[ok]], axis=1))
    return verts, np.concatenate(faces).astype(np.int64)


def _rotation(yaw_deg: float, pitch_deg: float) -> np.ndarray:
    y, p = math.radians(yaw_deg), math.radians(pitch_deg)
    ry = np.array([[math.cos(y), 0, math.sin(y)], [0, 1, 0], [-math.sin(y), 0, math.cos(y)]])
    rx = np.array([[1, 0, 0], [0, math.cos(p), -math.sin(p)], [0, math.sin(p), math.cos(p)]])
    return ry @ rx


def render_view(
    depth_mm: npt.ArrayLike,
    camera: PinholeCamera,
    *,
    yaw_deg: float = 35.0,
    pitch_deg: float = 20.0,
    min_width_px: int = 640,
    edge_mm: float = 100.0,
    shading: str = "gray",
) -> np.ndarray:
    """Render a depth frame as a lit 3-D surface from a rotated viewpoint (BGR uint8).

    Parameters
    ----------
    depth_mm : array_like (h, w)
        Depth in mm, 0 = none.
    camera : PinholeCamera
        Intrinsics of the frame.
    yaw_deg, pitch_deg : float
        Rotation of the viewpoint about the scene's median point (left/right, up/down).
    min_width_px : int
        The picture is rendered with the frame's camera enlarged by an integer factor to at
        least this width.
    edge_mm : float
        Largest depth span of a triangle (no surface across depth jumps).
    shading : {"gray", "depth"}
        Grey Lambertian shading (as in the paper's figures) or shading × depth colours.
    """
    if shading not in ("gray", "depth"):
        raise InputError(f"shading must be 'gray' or 'depth', got {shading!r}")
    if not (math.isfinite(edge_mm) and edge_mm > 0):
        raise InputError(f"edge_mm must be > 0, got {edge_mm!r}")
    verts, faces = depth_mesh(depth_mm, camera, edge_mm)
    d = as_depth_frame(depth_mm, name="depth")
    if not len(faces):
        raise InputError("the frame has no surface to show (no 2x2 block of valid depth)")
    centre = np.median(verts.reshape(*d.shape, 3)[d > 0], axis=0)
    rot = _rotation(yaw_deg, pitch_deg)
    eye = centre + rot @ (-centre)
    pose = look_at(eye, centre, up=rot @ np.array([0.0, -1.0, 0.0]))
    k = max(1, math.ceil(min_width_px / camera.width))
    view_cam = camera.scaled(k)
    z = render_depth(verts, faces, view_cam, world_to_camera=pose).astype(np.float64)
    valid = z > 0
    xs, ys = view_cam.rays()
    pts = np.stack([xs * z, ys * z, z], axis=-1)
    gy = np.gradient(pts, axis=0)
    gx = np.gradient(pts, axis=1)
    n = np.cross(gx, gy)
    norm = np.linalg.norm(n, axis=-1, keepdims=True)
    n = np.divide(n, norm, out=np.zeros_like(n), where=norm > 0)
    view = -pts / np.maximum(np.linalg.norm(pts, axis=-1, keepdims=True), 1e-9)
    lambert = np.abs((n * view).sum(-1))
    shade = 0.25 + 0.75 * lambert
    img = np.full((*z.shape, 3), 255, np.uint8)
    if shading == "gray":
        g = np.clip(shade * 235.0, 0, 255).astype(np.uint8)
        img[valid] = g[valid][:, None]
    else:
        vals = d[d > 0]
        lo, hi = np.percentile(vals, [1, 99])
        col = colorize_depth(z, float(lo), float(max(hi, lo + 1.0))).astype(np.float64)
        img[valid] = np.clip(col[valid] * shade[valid][:, None], 0, 255).astype(np.uint8)
    return img
