"""Input checks shared by the baselines: a frame or a video of depth (the SR factor:
:func:`upsr.method.upsampling._check_scale`)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from upsr.errors import InputError
from upsr.method.validation import as_depth_frame

__all__: list[str] = []


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
