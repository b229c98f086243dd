"""upsr.io.color: colour images resampled onto the output grid."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

import upsr.io as uio
from tests.io._frames import NAMES
from upsr.errors import InputError


def test_resample_color_geometry() -> None:
    img = np.zeros((4, 6, 3), np.uint8)
    img[:, :, 1] = np.arange(6, dtype=np.uint8)[None, :] * 40
    out = uio.resample_color(img, (8, 12))
    assert out.shape == (8, 12, 3) and out.dtype == np.uint8
    # SPEC §1: output column j' sits at input x = (j' + 0.5)/2 - 0.5
    j = np.arange(12)
    expect = np.clip((j + 0.5) / 2 - 0.5, 0, 5) * 40
    np.testing.assert_allclose(out[3, :, 1], expect, atol=1)
    grey16 = np.arange(12, dtype=np.uint16).reshape(3, 4) * 1000
    assert uio.resample_color(grey16, (6, 8)).dtype == np.uint16
    assert uio.resample_color(img, (2, 3)).shape == (2, 3, 3)


def test_write_color_folder(tmp_path: Path) -> None:
    src = tmp_path / "rgb"
    src.mkdir()
    for n in NAMES:
        cv2.imwrite(str(src / f"{n}.jpg"), np.full((6, 8, 3), 77, np.uint8))
    out = uio.write_color(src, tmp_path / "o.color", (12, 16), n_frames=3)
    assert sorted(p.name for p in out.iterdir()) == [f"{n}.png" for n in NAMES]
    assert cv2.imread(str(out / f"{NAMES[0]}.png")).shape == (12, 16, 3)
    with pytest.raises(InputError, match="already exists"):
        uio.write_color(src, out, (12, 16))
    with pytest.raises(InputError, match="3 colour image"):
        uio.write_color(src, tmp_path / "p", (12, 16), n_frames=4)
    assert not (tmp_path / "p").exists()
    one = uio.write_color(src / f"{NAMES[1]}.jpg", tmp_path / "q", (3, 4), frame_names=["f"])
    assert [p.name for p in one.iterdir()] == ["f.png"]
