"""`upsr experiment cumulative` (paper Fig. 2) in quick mode (a synthetic scene)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from tests.research.experiments._helpers import read_csv
from upsr.apps.cli import main as cli
from upsr.method.upsampling import upsample_nearest
from upsr.research.experiments.cumulative import (
    CSV_COLUMNS,
    VARIANTS,
    fuse_with_registration,
    upscale_flow,
)


def test_upscale_flow_scales_vectors_and_grid() -> None:
    flow = np.zeros((3, 4, 2), np.float32)
    flow[..., 0], flow[..., 1] = 0.5, -1.0
    big = upscale_flow(flow, 4)
    assert big.shape == (12, 16, 2)
    np.testing.assert_allclose(big[..., 0], 2.0)
    np.testing.assert_allclose(big[..., 1], -4.0)


@pytest.mark.parametrize("variant", [v for v in VARIANTS if v != "upsr_fused"])
def test_static_video_fuses_to_the_upsampled_frame(variant: str) -> None:
    y, x = np.mgrid[0:20, 0:24]
    frame = (1500.0 + 20.0 * x + 10.0 * y).astype(np.float32)
    frame[5:12, 6:14] = 900.0
    video = np.stack([frame] * 5)
    fused, stacks = fuse_with_registration(video, 2, 5, [2], variant)
    np.testing.assert_array_equal(fused[0], upsample_nearest(frame, 2))
    assert stacks[0].shape == (5, 40, 48)


def test_command_writes_tables_and_plots(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "cum"
    rc = cli.main(
        ["experiment", "cumulative", "--quick", "--data", str(tmp_path), "-o", str(out), "-q"]
    )
    assert rc == 0
    assert "Cumulative registration" in capsys.readouterr().out
    header, rows = read_csv(out / "cumulative.csv")
    assert header == list(CSV_COLUMNS)
    assert {r["variant"] for r in rows} == set(VARIANTS)
    assert {float(r["sigma"]) for r in rows} == {0.0, 30.0}
    rmse = {(r["variant"], float(r["sigma"])): float(r["rmse"]) for r in rows}
    # registering the moving object beats not registering it at all
    for v in ("non_cumulative", "cumulative_lowres", "cumulative_upsampled", "upsr_fused"):
        assert rmse[(v, 0.0)] < rmse[("none", 0.0)]
    dh, drows = read_csv(out / "cumulative_distance.csv")
    assert dh[:4] == ["variant", "sigma", "distance", "misregistered"]
    assert {int(r["distance"]) for r in drows} == {1, 2}
    for name in ("cumulative.png", "cumulative_distance.png"):
        assert cv2.imread(str(out / name)) is not None
    assert "(c) cumulative, upsampled" in (out / "summary.md").read_text()


def test_reference_at_the_end_of_the_window(tmp_path: Path) -> None:
    out = tmp_path / "cum"
    rc = cli.main(
        ["experiment", "cumulative", "--quick", "--reference", "last", "-o", str(out), "-q"]
    )
    assert rc == 0
    _, rows = read_csv(out / "cumulative.csv")
    assert "upsr_fused" not in {r["variant"] for r in rows}
    _, drows = read_csv(out / "cumulative_distance.csv")
    assert max(int(r["distance"]) for r in drows) == 4
