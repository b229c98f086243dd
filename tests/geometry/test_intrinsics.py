"""upsr.geometry.intrinsics: the OUTPUT.intrinsics.json sidecar, written and read back."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

import upsr.io as uio
from tests.io._frames import _video
from upsr.geometry.camera import PinholeCamera
from upsr.geometry.intrinsics import load_intrinsics, write_intrinsics


def test_intrinsics_json_carries_stamps_names(tmp_path: Path) -> None:
    cam = PinholeCamera(100.0, 101.0, 63.5, 47.5, 128, 96)
    p = write_intrinsics(
        tmp_path / "o.npy.intrinsics.json", cam, timestamps_ns=[5, 6], frame_names=["x", "y"]
    )
    d = json.loads(p.read_text())
    assert d["timestamps_ns"] == [5, 6] and d["frame_names"] == ["x", "y"]
    assert d["intrinsic_matrix"] == [100.0, 0.0, 0.0, 0.0, 101.0, 0.0, 63.5, 47.5, 1.0]
    assert load_intrinsics(p) == cam
    np.save(tmp_path / "o.npy", _video(2))
    np.testing.assert_array_equal(uio.read_timestamps(tmp_path / "o.npy"), [5, 6])
