"""PLACEHOLDER being written: UP-SR video pipeline (streaming engine and batch API)."""

from __future__ import annotations

import numpy as np

from .config import UPSRConfig
from .upsampling import upsample_nearest
from .validation import as_depth_video


def super_resolve(frames, scale, n_frames=9, *, config=None, progress=None, **options):
    cfg = config or UPSRConfig.from_options(scale, n_frames, **options)
    video = as_depth_video(frames)
    return upsample_nearest(video, cfg.scale).astype(np.float32)
