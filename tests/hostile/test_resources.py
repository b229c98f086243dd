"""The resource model refuses runs that cannot fit, before anything is allocated."""

from __future__ import annotations

import tracemalloc
from pathlib import Path

import pytest

from upsr.errors import InputError
from upsr.method import resources
from upsr.method.config import UPSRConfig

from .conftest import assert_one_line


@pytest.mark.parametrize("r", [150, 1000])
def test_huge_scale_refused_before_allocating(r: int, tmp_path: Path) -> None:
    with pytest.raises(InputError, match="scale r"):
        UPSRConfig(scale=r)  # the option bound
    tracemalloc.start()
    try:
        with pytest.raises(InputError, match=r"needs ~.* GB of memory.*--max-memory") as e:
            resources.check_resources(
                (9, 56, 64), r, 9, output=tmp_path / "o.npy", max_memory=4 << 30
            )
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert_one_line(e)
    assert peak < 1 << 20


def test_model_numbers() -> None:
    """The estimate covers every peak of the module docstring (tracemalloc rows, workers 0;
    resident peaks over the process of benchmarks/memory_eval.py, workers 2), within 4×: at
    r = 16 it was 4× too low, and a run that passed the check could be killed half-way."""
    for shape, r, n, k, mb in [
        ((12, 64, 56), 2, 9, 0, 9.7),
        ((12, 128, 112), 4, 9, 0, 48.3),
        ((12, 128, 112), 4, 5, 0, 26.0),
        ((14, 240, 320), 2, 9, 0, 208.5),
        ((9, 240, 320), 4, 9, 2, 467),
        ((9, 480, 640), 2, 9, 2, 1356),
        ((5, 240, 320), 8, 5, 2, 785),
        ((1, 480, 640), 8, 1, 2, 1046),
        ((3, 480, 640), 8, 3, 2, 2662),
        ((1, 480, 640), 16, 1, 2, 4010),
    ]:
        est = resources.peak_memory_bytes(shape, r, n, k) / 2**20
        assert mb <= est <= 4 * mb + 64, (shape, r, n, est, mb)  # (+ its fixed 40 MB)
    assert resources.output_bytes((10, 100, 200), 2, "npy") == 10 * 200 * 400 * 4 + 4096
    assert resources.output_bytes((10, 100, 200), 2, "png") < resources.output_bytes(
        (10, 100, 200), 2, "npy"
    )


def test_small_run_accepted_and_override(tmp_path: Path) -> None:
    est = resources.check_resources((9, 56, 64), 2, 9, output=tmp_path / "o.npy")
    assert est.peak_memory_bytes < est.memory_available
    resources.check_resources((9, 56, 64), 16, 9, max_memory=1 << 40)
    with pytest.raises(InputError, match="needs"):
        resources.check_resources((9, 56, 64), 2, 9, max_memory=1000)


def test_disk_check(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(resources, "free_disk_bytes", lambda p: 1000)
    with pytest.raises(InputError, match="of disk") as e:
        resources.check_resources((9, 56, 64), 2, 9, output=tmp_path / "o.npy")
    assert_one_line(e)


def test_available_memory_and_parse_bytes() -> None:
    assert resources.available_memory_bytes() > 0
    assert resources.parse_bytes("4G") == 4 << 30
    assert resources.parse_bytes("512MiB") == 512 << 20
    assert resources.parse_bytes(1e9) == 10**9
    for bad in ("x", "-1G", "nan", "inf", True):
        with pytest.raises(InputError):
            resources.parse_bytes(bad)  # type: ignore[arg-type]
