"""``upsr batch``: a real Dask cluster, failures reported per recording, resuming."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.apps._util import N, R, check_batch_output
from upsr.apps.cli.main import main


def test_batch_on_dask_cluster(videos, tmp_path: Path) -> None:
    distributed = pytest.importorskip("dask.distributed")
    d, ref = videos
    with distributed.LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=None,
    ) as cluster:
        code = main(
            [
                "batch",
                str(d / "a.npy"),
                str(d / "b.npy"),
                "--out",
                str(tmp_path),
                "-r",
                str(R),
                "-n",
                str(N),
                "--chunk-frames",
                "4",
                "--scheduler",
                cluster.scheduler_address,
                "-q",
            ]
        )
    assert code == 0
    check_batch_output(tmp_path, ref)


def test_batch_failures_and_resume(videos, tmp_path: Path, capsys) -> None:
    d, ref = videos
    bad = tmp_path / "bad.npy"
    bad.write_bytes(b"\x93NUMPY garbage")
    short = tmp_path / "short.npy"
    np.save(short, np.load(d / "b.npy")[:3])
    out = tmp_path / "out"
    args = [
        "batch",
        str(bad),
        str(d / "b.npy"),
        str(short),
        "--out",
        str(out),
        "-r",
        str(R),
        "-n",
        str(N),
        "-w",
        "1",
        "-q",
    ]
    assert main(args) == 2
    cap = capsys.readouterr()
    assert "1 done, 0 skipped (output exists), 2 failed" in cap.out
    assert "bad.npy: unsupported .npy format" in cap.err and "N=5 > 3 frames in" in cap.err
    np.testing.assert_array_equal(np.load(out / "b.npy"), ref["b"])
    assert sorted(p.name for p in out.iterdir()) == [".upsr-batch", "b.npy"]  # nothing partial
    assert [p.name for p in (out / ".upsr-batch" / "outputs").iterdir()] == ["b.npy.json"]
    # default N shrinks to a short recording, as in `upsr run`
    assert main(["batch", str(short), "--out", str(out), "-r", "1", "-q", "-w", "1"]) == 0
    assert np.load(out / "short.npy").shape == (3, 20, 24)
    assert main(["batch", str(d / "b.npy"), str(d / "b.npy"), "--out", str(out), "-r", "2"]) == 2
