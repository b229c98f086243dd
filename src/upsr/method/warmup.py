"""Warm-up: every compiled kernel of an engine loaded before a live stream starts.

Beyond the paper. numba compiles the method's kernels once per machine (``cache=True``) and
loads them from that cache in each new process the first time they run; OpenCV allocates its
flow's buffers on the first frame of a size. In a new process the first frame of a live
camera therefore takes several times a steady frame (0.3 s at 256×192, against 45 ms: the
camera's next ten frames are dropped and the first outputs come late). :func:`warm_up` runs a
few synthetic frames of the stream's size through throw-away engines of the same
configuration, before the stream starts: what the first real frame would load is loaded, and
nothing of the synthetic frames reaches the real engine (whose output is therefore the same
with or without a warm-up).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from upsr.errors import InputError
from upsr.method.config import UPSRConfig

__all__ = ["WARM_UP_FRAMES", "warm_up", "warm_up_frames"]

#: Frames per throw-away engine: the first (statistics, restart from the anchor), the second
#: (the first flow, the temporal noise) and a third in steady state.
WARM_UP_FRAMES = 3


def warm_up_frames(shape_px: tuple[int, int], n_frames: int = WARM_UP_FRAMES) -> np.ndarray:
    """Synthetic depth frames (mm) of ``shape_px``: a slanted wall 2–2.6 m away, a box 1 m
    in front of it moving one pixel per frame and 60 mm nearer (the recursive mode measures
    such an offset twice), Laplacian noise of σ = 10 mm and 1 % of the pixels without depth
    (0), from a fixed seed.

    Parameters
    ----------
    shape_px : (int, int)
        (h, w) of the frames, each at least 2.
    n_frames : int
        T.

    Returns
    -------
    ndarray float32 (T, h, w)
    """
    h, w = (int(v) for v in shape_px)
    if h < 2 or w < 2 or n_frames < 1:
        raise InputError(f"warm-up frames need h, w >= 2 and T >= 1, got {shape_px}, {n_frames}")
    rng = np.random.default_rng(0)
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float32)
    out = np.empty((n_frames, h, w), np.float32)
    for t in range(n_frames):
        z = 2000.0 + 600.0 * xs / w + 100.0 * ys / h
        y0, x0 = h // 3, w // 4 + t
        z[y0 : y0 + max(h // 3, 1), x0 : x0 + max(w // 4, 1)] -= 1000.0 + 60.0 * t
        z += rng.laplace(0.0, 10.0 / np.sqrt(2.0), z.shape).astype(np.float32)
        z[rng.random(z.shape) < 0.01] = 0.0
        out[t] = z
    return out


def warm_up(config: UPSRConfig, shape_px: tuple[int, int]) -> None:
    """Load every kernel that an engine of ``config`` runs on frames of ``shape_px``.

    Runs :func:`warm_up_frames` through throw-away engines of ``config`` (the windowed or the
    recursive one, per ``config.mode``); with ``remove_mixed="auto"``, once without and once
    with the removal of mixed pixels (whichever the real video turns out to need); the depth
    companded beyond 2.3 m (:mod:`upsr.method.companding`) unless ``compand_knee_mm`` is
    None. Costs a few frames' time; nothing is kept but what numba and OpenCV load.

    Parameters
    ----------
    config : UPSRConfig
        The configuration of the engine that will run.
    shape_px : (int, int)
        (h, w) of its low-res frames.
    """
    from upsr.method.recursive import RecursiveUPSR
    from upsr.method.windowed import UPSR

    frames = warm_up_frames(shape_px)
    removal = (False, True) if config.remove_mixed == "auto" else (config.remove_mixed,)
    for remove in removal:
        # (the synthetic frames whatever range the video keeps: the kernels are the same; their
        # far side companded, as a Kinect's beyond 5.8 m, unless the video never is)
        knee = None if config.compand_knee_mm is None else 2300.0
        cfg = dataclasses.replace(
            config, remove_mixed=remove, valid_range_mm=None, compand_knee_mm=knee
        )
        if cfg.mode == "recursive":
            engine = RecursiveUPSR(config=cfg, workers=0)
            for frame in frames:
                engine.push(frame)
        else:  # (the kernels do not depend on N: a window of the warm-up's frames)
            cfg = dataclasses.replace(cfg, n_frames=min(cfg.n_frames, len(frames)))
            for _ in UPSR(config=cfg, workers=0).process(frames):
                pass
