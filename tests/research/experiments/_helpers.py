"""Small synthetic stand-ins for the shared data (no test reads ../shared)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest

# The 12 triangles of a box whose 8 corners are numbered by bits (x, y, z) of the index.
_BOX_FACES = (
    (0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5),  # x = lo, x = hi
    (0, 4, 5), (0, 5, 1), (2, 3, 7), (2, 7, 6),  # y = lo, y = hi
    (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3),  # z = lo, z = hi
)  # fmt: skip


def _box(lo: tuple[float, float, float], hi: tuple[float, float, float], base: int) -> list[str]:
    lines = []
    for k in range(8):
        x = hi[0] if k & 4 else lo[0]
        y = hi[1] if k & 2 else lo[1]
        z = hi[2] if k & 1 else lo[2]
        lines.append(f"v {x:.4f} {y:.4f} {z:.4f}")
    lines += [f"f {a + base + 1} {b + base + 1} {c + base + 1}" for a, b, c in _BOX_FACES]
    return lines


def write_obj_sequence(folder: Path, n: int, step_m: float = 0.03) -> list[Path]:
    """A 'person' of two boxes (body and head, metres, Y up) moving sideways, as samba/*.obj."""
    samba = folder / "samba"
    samba.mkdir(parents=True, exist_ok=True)
    paths = []
    for k in range(n):
        dz = k * step_m
        lines = _box((-0.15, 0.0, -0.4 + dz), (0.15, 1.2, 0.3 + dz), 0)
        lines += _box((-0.3, 1.25, -0.2 + dz), (-0.1, 1.6, 0.1 + dz), 8)
        path = samba / f"mesh_{k:04d}.obj"
        path.write_text("\n".join(lines) + "\n")
        paths.append(path)
    return paths


def synthetic_disparity(h: int = 64, w: int = 80, seed: int = 0) -> np.ndarray:
    """A Middlebury-like 8-bit disparity: slanted background, discs, texture, a small hole."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:h, 0:w].astype(float)
    d = 60 + 0.4 * x + 0.2 * y
    for _ in range(6):
        cy, cx = rng.uniform(8, h - 8), rng.uniform(8, w - 8)
        m = (y - cy) ** 2 + (x - cx) ** 2 < rng.uniform(4, 10) ** 2
        d[m] = rng.uniform(100, 200) + 0.5 * (x[m] - cx)
    d += 6 * np.sin(x / 3.0) * np.cos(y / 4.0)
    out = np.clip(np.rint(d), 1, 255).astype(np.uint8)
    out[20:22, 30:33] = 0
    return out


def write_disparity(folder: Path, disparity: np.ndarray | None = None) -> Path:
    """Write ``folder/middlebury/art/disp1.png``."""
    path = folder / "middlebury" / "art" / "disp1.png"
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), synthetic_disparity() if disparity is None else disparity)
    return path


@pytest.fixture
def stand_in_data(tmp_path: Path) -> Callable[..., Path]:
    """Factory: a data folder with a disparity PNG and/or an OBJ sequence of n meshes."""

    def make(*, disparity: bool = True, meshes: int = 0) -> Path:
        data = tmp_path / "data"
        data.mkdir(exist_ok=True)
        if disparity:
            write_disparity(data)
        if meshes:
            write_obj_sequence(data, meshes)
        return data

    return make


def read_csv(path: Path) -> tuple[list[str], list[dict[str, str]]]:
    """Header and rows of a CSV file."""
    import csv

    with open(path, newline="") as fh:
        reader = csv.DictReader(fh)
        rows = list(reader)
        return list(reader.fieldnames or []), rows
