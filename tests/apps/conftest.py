"""Fixtures shared by the tests of upsr.apps."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import upsr
from tests.apps._util import N, R
from upsr.research.synth.scenes import dynamic_scene


@pytest.fixture(scope="session")
def videos(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, np.ndarray]]:
    """Two short noisy moving scenes (13 and 9 frames) and their single-run results."""
    d = tmp_path_factory.mktemp("rec")
    a = dynamic_scene(n_frames=13, lowres_shape=(20, 24), scale=R, noise_sigma_mm=20, seed=1)
    b = dynamic_scene(n_frames=9, lowres_shape=(20, 24), scale=R, noise_sigma_mm=30, seed=2)
    np.save(d / "a.npy", a.lowres)
    np.save(d / "b.npy", b.lowres)
    ref = {k: upsr.super_resolve(v.lowres, R, N) for k, v in (("a", a), ("b", b))}
    return d, ref
