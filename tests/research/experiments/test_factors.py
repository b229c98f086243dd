"""`upsr experiment factors` (paper Fig. 7) and `all` in quick mode on stand-in data."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import cv2
import pytest

from tests.research.experiments._helpers import read_csv
from upsr.apps.cli import main as cli
from upsr.research.analysis import median_variance
from upsr.research.experiments.factors import CSV_COLUMNS


def test_command_writes_model_and_simulation(
    stand_in_data: Callable[..., Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = stand_in_data(disparity=False, meshes=5)
    out = tmp_path / "factors"
    rc = cli.main(["experiment", "factors", "--quick", "--data", str(data), "-o", str(out), "-q"])
    assert rc == 0
    assert "MSE vs noise for SR factors" in capsys.readouterr().out
    header, rows = read_csv(out / "factors.csv")
    assert header == list(CSV_COLUMNS)
    assert {(r["pipeline"], int(r["r"]), r["stage"]) for r in rows} == {
        (p, r, s)
        for p in ("upsr", "upsr_no_suppression")
        for r in (1, 2, 4)
        for s in ("fusion", "deblurred")
    }
    for row in rows:
        sigma, r = float(row["sigma"]), int(row["r"])
        assert float(row["theory_variance"]) == pytest.approx(
            float(median_variance(5, sigma)), rel=1e-5
        )
        if r == 1:  # no upsampling, no bias: the model is the median variance
            assert float(row["rho_mm"]) == 0.0
            assert float(row["theory_mse"]) == pytest.approx(
                float(row["theory_variance"]), rel=1e-5
            )
        assert math.isfinite(float(row["surface_mse"]))
    assert cv2.imread(str(out / "factors.png")) is not None
    assert cv2.imread(str(out / "factors_default.png")) is not None
    assert "model" in (out / "summary.md").read_text()


def test_all_writes_a_report(
    stand_in_data: Callable[..., Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = stand_in_data(disparity=True, meshes=10)
    out = tmp_path / "results"
    rc = cli.main(["experiment", "all", "--quick", "--data", str(data), "-o", str(out), "-q"])
    assert rc == 0
    assert "report written" in capsys.readouterr().out
    report = (out / "REPORT.md").read_text()
    for name, png in (
        ("motion-accuracy", "motion_accuracy.png"),
        ("cumulative", "cumulative.png"),
        ("noise", "noise.png"),
        ("factors", "factors.png"),
    ):
        assert (out / name / png).is_file()
        assert f"]({name}/{png})" in report
        assert (out / name / "summary.md").is_file()
    assert report.count("| r |") >= 1 and "## Motion accuracy" in report


def test_out_must_be_a_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    target = tmp_path / "file"
    target.write_text("x")
    rc = cli.main(["experiment", "cumulative", "--quick", "-o", str(target)])
    assert rc == 2
    assert "is not a folder" in capsys.readouterr().err
