"""Input checks shared by the baselines: the SR factor, a frame or a video of depth."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from upsr.errors import InputError
from upsr.method.validation import as_depth_frame

__all__: list[str] = []


def _check_scale(r: int) -> int:
    if isinstance(r, bool) or not isinstance(r, (int, np.integer)) or r < 1:
        raise InputError(f"scale r must be an integer >= 1, got {r!r}")
    return int(r)


def _as_frames(lowres: npt.ArrayLike) -> tuple[np.ndarray, bool]:
    """(T, h, w) float32 with invalid = 0, and whether the input was a single (h, w) frame."""
    arr = np.asarray(lowres)
    if arr.ndim == 2:
        return as_depth_frame(arr, name="lowres")[None], True
    if arr.ndim == 3 and arr.shape[0] > 0:
        return np.stack(
            [as_depth_frame(f, name=f"lowres frame {t}") for t, f in enumerate(arr)]
        ), False
    raise InputError(
        f"lowres: expected a depth frame (h, w) or video (T, h, w), got shape {arr.shape}"
    )
