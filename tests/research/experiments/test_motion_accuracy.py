"""`upsr experiment motion-accuracy` (paper Table 2) on a synthetic disparity stand-in."""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest

from tests.research.experiments._helpers import read_csv, synthetic_disparity
from upsr.apps.cli import main as cli
from upsr.errors import InputError
from upsr.research.experiments.data import disparity_to_depth_mm, load_middlebury_art
from upsr.research.experiments.motion_accuracy import (
    CSV_COLUMNS,
    ESTIMATORS,
    _trend_ok,
    dis_scaled,
    measure_motion_accuracy,
    select_estimator,
    shifted_pair,
    valid_interior,
)


def test_disparity_to_depth_follows_spec() -> None:
    disp = np.array([[0, 1, 100, 255]], np.uint8)
    depth = disparity_to_depth_mm(disp)
    assert depth[0, 0] == 0
    np.testing.assert_allclose(
        depth[0, 1:], 3740 * 160 / (np.array([1, 100, 255]) + 200), rtol=1e-6
    )


def test_load_art_reads_the_png(stand_in_data: Callable[..., Path]) -> None:
    data = stand_in_data()
    depth = load_middlebury_art(data)
    assert depth.shape == (64, 80) and depth.dtype == np.float32
    assert (depth == 0).sum() == 6  # the hole of the stand-in
    with pytest.raises(InputError, match="missing Middlebury"):
        load_middlebury_art(data / "nowhere")


def test_shifted_pair_is_an_exact_one_pixel_motion() -> None:
    depth = disparity_to_depth_mm(synthetic_disparity())
    first, second = shifted_pair(depth)
    assert first.shape == second.shape == (63, 79)
    # second(p + (1, 1)) = first(p)
    np.testing.assert_array_equal(second[1:, 1:], first[:-1, :-1])
    mask = valid_interior(first, 8)
    assert not mask[:8].any() and not mask[:, -8:].any()
    assert not mask[first == 0].any()


def test_error_falls_with_r_on_a_synthetic_disparity() -> None:
    depth = disparity_to_depth_mm(synthetic_disparity())
    rows = measure_motion_accuracy(depth, (1, 2, 4, 8), ("dis-medium", "dis-fast"))
    assert {r["estimator"] for r in rows} == {"dis-medium", "dis-fast"}
    best = select_estimator(rows)
    errs = [
        r["error_mean_px"] for r in sorted(rows, key=lambda r: r["r"]) if r["estimator"] == best
    ]
    assert errs[0] > 0.05  # r = 1: sub-pixel but visible error
    assert all(b <= a + 1e-9 for a, b in itertools.pairwise(errs))
    assert errs[-1] <= 0.3 * errs[0]


def test_dis_scaled_recovers_an_integer_shift_at_every_r() -> None:
    depth = disparity_to_depth_mm(synthetic_disparity())
    img = np.clip((depth - 1500) / 4, 1, 255).astype(np.uint8)
    for r in (1, 3, 6):
        big = cv2.resize(img, None, fx=r, fy=r, interpolation=cv2.INTER_NEAREST)
        first, second = big[r:, r:], big[:-r, :-r]  # true motion (r, r)
        flow = dis_scaled(r)(np.ascontiguousarray(first), np.ascontiguousarray(second))
        assert flow.shape == (*first.shape, 2) and flow.dtype == np.float32
        inner = flow[8 * r : -8 * r, 8 * r : -8 * r] / r
        assert np.median(np.abs(inner - 1.0)) < 0.05
    with pytest.raises(InputError):
        dis_scaled(0)


def test_trend_check_allows_the_paper_precision_only() -> None:
    assert _trend_ok([0.5, 0.25, 0.13, 0.08, 0.06])
    assert _trend_ok([0.12, 0.04, 0.002, 0.006, 0.001])  # +0.004 px: below 0.01 px
    assert not _trend_ok([3.6, 0.13, 0.11, 0.36, 0.10])  # the r = 6 bump of dis-medium
    assert not _trend_ok([0.5, 0.4, 0.3, 0.2])  # eps_R > 0.3 eps_1


def test_scaled_dis_error_falls_with_r_including_r6() -> None:
    depth = disparity_to_depth_mm(synthetic_disparity())
    rows = measure_motion_accuracy(depth, (1, 2, 4, 6, 8), ("dis-medium-r",), margin_px=4)
    errs = [r["error_mean_px"] for r in sorted(rows, key=lambda r: r["r"])]
    # the synthetic stand-in is easy (eps_1 is already ~0.01 px): no factor may be worse
    assert all(e2 <= 1.1 * e1 + 0.01 for e1, e2 in itertools.pairwise(errs)), errs
    assert max(errs) < 0.05
    assert select_estimator(rows) == "dis-medium-r"


def test_unknown_estimator_is_rejected() -> None:
    depth = disparity_to_depth_mm(synthetic_disparity())
    with pytest.raises(InputError, match="unknown estimator"):
        measure_motion_accuracy(depth, (1, 2), ("dis-huge",))


def test_command_writes_csv_plot_and_summary(
    stand_in_data: Callable[..., Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = stand_in_data()
    out = tmp_path / "out"
    rc = cli.main(
        ["experiment", "motion-accuracy", "--quick", "--data", str(data), "-o", str(out), "-q"]
    )
    assert rc == 0
    assert "Motion accuracy vs upsampling" in capsys.readouterr().out
    header, rows = read_csv(out / "motion_accuracy.csv")
    assert header[:2] == ["r", "error_px"] and header == list(CSV_COLUMNS)
    assert [int(r["r"]) for r in rows] == [1, 2, 4, 8]
    errs = [float(r["error_px"]) for r in rows]
    assert all(math.isfinite(e) and e >= 0 for e in errs)
    assert errs[-1] < errs[0]
    assert [float(r["paper_error_px"]) for r in rows] == [0.51, 0.25, 0.13, 0.06]
    _, all_rows = read_csv(out / "motion_accuracy_all.csv")
    assert {r["estimator"] for r in all_rows} == set(ESTIMATORS)
    assert sum(r["selected"] == "True" for r in all_rows) == 4
    img = cv2.imread(str(out / "motion_accuracy.png"))
    assert img is not None and img.shape[2] == 3
    assert "| r | paper eps" in (out / "summary.md").read_text()


def test_missing_data_is_a_user_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rc = cli.main(
        ["experiment", "motion-accuracy", "--data", str(tmp_path), "-o", str(tmp_path / "o")]
    )
    assert rc == 2
    assert "missing Middlebury disparity" in capsys.readouterr().err
