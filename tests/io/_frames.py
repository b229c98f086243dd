"""Small depth frames and TUM-named PNG folders for the tests of tests/io (and geometry)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

NAMES = ["1305031102.175304", "1305031102.211214", "1305031102.243211"]


def _png_folder(path: Path, frames: np.ndarray, names: list[str]) -> Path:
    path.mkdir()
    for f, n in zip(frames, names, strict=True):
        cv2.imwrite(str(path / f"{n}.png"), f.astype(np.uint16))
    return path


def _video(t: int = 3) -> np.ndarray:
    return np.stack([np.full((6, 8), 1000.0 + 10 * k, np.float32) for k in range(t)])
