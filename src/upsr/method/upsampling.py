"""Dense (nearest-neighbour) upsampling U and its adjoint, paper eq. 13–15.

Pixel geometry (``SPEC.md`` §1): low-res pixel (i, j) covers the high-res block rows
r·i … r·i+r−1, cols r·j … r·j+r−1 and sits at their mean, high-res coordinate (i+0.5)·r − 0.5.
"""

from __future__ import annotations

import cv2
import numpy as np
import numpy.typing as npt

from upsr.errors import InputError
from upsr.method.config import MAX_SCALE

__all__ = [
    "decimate",
    "downsample_mean",
    "resample_nearest",
    "upsample_bicubic",
    "upsample_nearest",
]


def _check_scale(r: int) -> int:
    """``r`` as an int, 1 ≤ r ≤ :data:`~upsr.method.config.MAX_SCALE` (beyond, a frame's
    output alone would not fit in memory: r = 10000 took 24 GB for a 4×4 frame)."""
    if isinstance(r, bool) or not isinstance(r, (int, np.integer)) or not 1 <= r <= MAX_SCALE:
        raise InputError(f"scale r must be an integer in 1..{MAX_SCALE}, got {r!r}")
    return int(r)


def upsample_nearest(y: npt.ArrayLike, r: int) -> np.ndarray:
    """Dense upsampling y↑ = U y (eq. 13–15): replicate each pixel into an r×r block.

    Parameters
    ----------
    y : array_like, shape (..., h, w)
        Low-res depth (mm); invalid pixels (0) stay invalid, they are never interpolated.
    r : int
        Upsampling factor (≥ 1).

    Returns
    -------
    ndarray, shape (..., r·h, r·w), same dtype as ``y``.

    Examples
    --------
    >>> import numpy as np
    >>> upsample_nearest(np.array([[1000, 0]], np.float32), 2)
    array([[1000., 1000.,    0.,    0.],
           [1000., 1000.,    0.,    0.]], dtype=float32)
    """
    r = _check_scale(r)
    y = np.asarray(y)
    if r == 1:
        return y.copy()
    return np.repeat(np.repeat(y, r, axis=-2), r, axis=-1)


def upsample_bicubic(y: npt.ArrayLike, r: int) -> np.ndarray:
    """Naive bicubic interpolation of depth frames, the conventional baseline of paper §7.

    ``cv2.resize`` with ``INTER_CUBIC`` per frame (half-pixel convention of ``SPEC.md`` §1,
    replicated border). Invalid pixels (0) are interpolated as if they were depth 0, as a naive
    bicubic would; the result is clipped at 0 (overshoot below 0 becomes "invalid"). Between
    foreground and background it creates intermediate depths: the *flying pixels* the paper
    criticises (Fig. 3 (b)).

    Parameters
    ----------
    y : array_like, shape (T, h, w), float32
        Depth (mm), 0 = invalid.
    r : int
        SR factor ≥ 1.

    Returns
    -------
    ndarray of float32, shape (T, r·h, r·w).
    """
    r = _check_scale(r)
    frames = np.asarray(y, dtype=np.float32)
    _, h, w = frames.shape
    if r == 1:
        return frames.copy()
    out = np.stack([cv2.resize(f, (w * r, h * r), interpolation=cv2.INTER_CUBIC) for f in frames])
    np.maximum(out, 0.0, out=out)
    return out


def decimate(x: npt.ArrayLike, r: int) -> np.ndarray:
    """The adjoint Uᵀ of dense upsampling: the sum over each r×r block.

    ``<U y, x> == <y, Uᵀ x>`` for all y, x (paper: U is the transpose of the decimation D up to
    the normalisation 1/r²; see :func:`downsample_mean`).

    Parameters
    ----------
    x : array_like, shape (..., r·h, r·w)
    r : int

    Returns
    -------
    ndarray, shape (..., h, w), float64 for integer input, else ``x``'s dtype.

    Examples
    --------
    >>> import numpy as np
    >>> decimate(np.ones((2, 4)), 2)
    array([[4., 4.]])
    """
    r = _check_scale(r)
    x = np.asarray(x)
    hh, ww = x.shape[-2:]
    if hh % r or ww % r:
        raise InputError(f"shape {x.shape[-2:]} is not divisible by r = {r}")
    blocks = x.reshape(*x.shape[:-2], hh // r, r, ww // r, r)
    dtype = np.float64 if np.issubdtype(x.dtype, np.integer) else x.dtype
    return blocks.sum(axis=(-3, -1), dtype=dtype)


def downsample_mean(x: npt.ArrayLike, r: int) -> np.ndarray:
    """Block-average decimation D = Uᵀ / r² (so that D U = I)."""
    r = _check_scale(r)
    return decimate(x, r) / (r * r)


def resample_nearest(depth_mm: npt.ArrayLike, shape: tuple[int, int]) -> np.ndarray:
    """Depth read at the pixel centres of a grid of ``shape`` covering the same field of view,
    from the nearest pixel (never interpolated across a depth edge; 0 stays "no depth").

    Parameters
    ----------
    depth_mm : array_like, shape (H, W)
        Depth (mm; 0: none), e.g. the recursive state on the output grid.
    shape : (h, w)
        The grid to read it on, e.g. the flow grid (any ratio, 4/3 included).

    Returns
    -------
    ndarray float32, shape (h, w)

    Examples
    --------
    >>> import numpy as np
    >>> resample_nearest(np.arange(16.0).reshape(4, 4), (2, 2)).tolist()
    [[5.0, 7.0], [13.0, 15.0]]
    """
    z = np.asarray(depth_mm, np.float32)
    big_h, big_w = z.shape
    h, w = (int(v) for v in shape)
    ys = np.minimum(((np.arange(h) + 0.5) * big_h / h).astype(np.intp), big_h - 1)
    xs = np.minimum(((np.arange(w) + 0.5) * big_w / w).astype(np.intp), big_w - 1)
    return np.ascontiguousarray(z[ys[:, None], xs[None, :]])
