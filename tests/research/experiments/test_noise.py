"""`upsr experiment noise` (paper Fig. 6) in quick mode on a tiny OBJ sequence."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest

from tests.research.experiments._helpers import read_csv
from upsr.apps.cli import main as cli
from upsr.research.experiments.noise import METHODS, search_deblur

SPEC_METRICS = ("rmse", "surface_rmse", "edge_accuracy", "flying_pixels", "missing", "invented")


def test_search_deblur_picks_the_smallest_error() -> None:
    rng = np.random.default_rng(0)
    truth = np.full((32, 32), 2000.0, np.float32)
    fused = truth + rng.laplace(0, 20, truth.shape).astype(np.float32)
    best, rows = search_deblur(fused, truth, 2, ((0.0, None), (1.0, None), (2.0, 30.0)))
    assert len(rows) == 3 and sum(r["chosen"] for r in rows) == 1
    chosen = next(r for r in rows if r["chosen"])
    assert chosen["heldout_mse"] == min(r["heldout_mse"] for r in rows)
    assert (best.lam, best.smooth_sigma_mm) == (chosen["lam"], chosen["smooth_sigma_mm"])
    assert chosen["lam"] > 0  # denoising helps on a flat noisy surface


def test_command_writes_every_method(
    stand_in_data: Callable[..., Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = stand_in_data(disparity=False, meshes=10)
    out = tmp_path / "noise"
    rc = cli.main(["experiment", "noise", "--quick", "--data", str(data), "-o", str(out), "-q"])
    assert rc == 0
    assert "MSE vs noise on Samba" in capsys.readouterr().out
    header, rows = read_csv(out / "noise.csv")
    assert header[:3] == ["method", "sigma", "mse"]
    assert set(SPEC_METRICS) <= set(header)
    assert {(r["method"], float(r["sigma"])) for r in rows} == {
        (m, s) for m in METHODS for s in (0.0, 50.0)
    }
    for r in rows:
        assert math.isfinite(float(r["mse"])) and float(r["mse"]) >= 0
    upsr = [r for r in rows if r["method"] == "upsr"]
    assert all(r["deblur_lam"] != "" for r in upsr)
    _, search = read_csv(out / "noise_deblur_search.csv")
    assert sum(r["chosen"] == "True" for r in search) == 2  # one choice per sigma
    assert cv2.imread(str(out / "noise.png")) is not None
    assert "MSE [mm²]" in (out / "noise.svg").read_text()
    assert "held-out" in (out / "summary.md").read_text()
    assert list((out / "cache").glob("samba_*.npz"))  # renders are cached


def test_missing_meshes_are_a_user_error(
    stand_in_data: Callable[..., Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = stand_in_data(disparity=False, meshes=3)
    rc = cli.main(
        ["experiment", "noise", "--quick", "--data", str(data), "-o", str(tmp_path / "o")]
    )
    assert rc == 2
    assert "missing Samba mesh" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()  # (the folder this run made is removed again)
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("kept")
    rc = cli.main(
        ["experiment", "noise", "--quick", "--data", str(data), "-o", str(tmp_path / "mine")]
    )
    assert rc == 2 and (tmp_path / "mine" / "notes.txt").read_text() == "kept"
