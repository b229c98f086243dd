"""The synthetic end-to-end demo on a tiny configuration."""

from __future__ import annotations

import csv
import json

import cv2
import numpy as np

from upsr.apps.demo import METRIC_COLUMNS, format_metrics_table, run_demo


def test_run_demo_writes_png_csv_json(tmp_path):
    out = tmp_path / "demo"
    res = run_demo(
        out,
        seed=1,
        scale=2,
        n_frames=3,
        noise_sigma_mm=20.0,
        progress=False,
        n_total_frames=5,
        lowres_shape=(16, 20),
    )
    png = cv2.imread(str(out / "demo.png"), cv2.IMREAD_COLOR)
    assert png is not None and png.ndim == 3 and png.shape[0] >= 32 and png.shape[1] > 5 * 40
    assert len(np.unique(png.reshape(-1, 3), axis=0)) > 50  # a real picture, not a blank

    with open(out / "metrics.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0]) == ["method", "frames", *METRIC_COLUMNS]
    assert {(r["method"], r["frames"]) for r in rows} == {
        (m, s) for m in ("nearest", "bicubic", "upsr") for s in ("middle", "all")
    }

    data = json.loads((out / "metrics.json").read_text())
    for selection in ("middle_frame", "all_frames"):
        assert set(data[selection]) == {"nearest", "bicubic", "upsr"}
        for method, metrics in res[selection].items():
            assert set(METRIC_COLUMNS) <= set(metrics)
            assert 0.0 <= metrics["missing"] <= 1.0
            assert data[selection][method]["rmse"] == metrics["rmse"]
    # the noisy input is not perfect, bicubic flies at the edges, nearest does not interpolate
    assert res["all_frames"]["nearest"]["rmse"] > 5.0
    assert (
        res["all_frames"]["bicubic"]["flying_pixels"]
        > res["all_frames"]["nearest"]["flying_pixels"]
    )
    assert res["config"]["middle_frame_index"] == 2

    table = format_metrics_table(res)
    assert "upsr" in table and "bicubic" in table and "edge_accuracy" in table
    assert "middle frame" in table and "all frames" in table
    lines = [ln for ln in table.splitlines() if ln.startswith("upsr")]
    assert len(lines) == 2


def test_format_metrics_table_plain_mapping():
    text = format_metrics_table({"x": {"rmse": 1.5, "edge_accuracy": float("nan")}})
    header, row = text.splitlines()
    assert header.startswith("method") and row.startswith("x")
    assert "1.5" in row and "n/a" in row
    assert len(header) == len(row)  # fixed width
