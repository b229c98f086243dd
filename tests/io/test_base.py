"""upsr.io._base: the checks every format shares."""

from __future__ import annotations

import numpy as np
import pytest

from upsr.errors import InputError
from upsr.io import _base


def test_check_frame_range() -> None:
    assert _base.check_frame_range(0, None, 5, "v") == (0, 5)
    assert _base.check_frame_range(np.int64(2), np.int32(4), 5, "v") == (2, 4)
    for start, stop in [(-1, None), (5, None), (1, 1), (0, 6)]:
        with pytest.raises(InputError, match=r"v: frames \["):
            _base.check_frame_range(start, stop, 5, "v")


def test_natural_key() -> None:
    names = ["f10.png", "F2.png", "f1.png", "g.png"]
    assert sorted(names, key=_base.natural_key) == ["f1.png", "F2.png", "f10.png", "g.png"]
    # times in seconds as str(float) writes them: fractions of any length by their value
    # (the fractions compared as integers put .1 before .0333333: frames read out of order)
    times = [f"{1700000000 + i / 30}.png" for i in range(8)]
    assert times[1] == "1700000000.0333333.png" and times[3] == "1700000000.1.png"
    assert sorted(times[::-1], key=_base.natural_key) == times


def test_reading_turns_failures_into_input_errors() -> None:
    with pytest.raises(InputError, match="x: corrupt or unreadable"), _base.reading("x"):
        raise ValueError("bad")
    with pytest.raises(InputError, match=r"x: compressed .* needs the imagecodecs package"):
        with _base.reading("x"):
            raise ValueError("<COMPRESSION.LZW: 5> requires the 'imagecodecs' package")
    with pytest.raises(InputError, match="x: cannot read"), _base.reading("x"):
        raise FileNotFoundError(2, "No such file")


@pytest.mark.parametrize(
    ("shape", "dtype", "match"),
    [
        ((2, 3, 4), object, "object arrays"),
        ((2, 3, 4), "U3", "numeric"),
        ((3, 4), float, "single frame"),
        ((0, 3, 4), float, "empty"),
        ((1, 1 << 15, 1 << 14), float, "too large"),
    ],
)
def test_check_array_meta(shape: tuple[int, ...], dtype: object, match: str) -> None:
    with pytest.raises(InputError, match=match):
        _base.check_array_meta("v", shape, np.dtype(dtype))


@pytest.mark.parametrize("scale", [0, -1, float("inf"), float("nan"), "x"])
def test_check_depth_scale(scale: object) -> None:
    with pytest.raises(InputError, match="depth_scale"):
        _base.check_depth_scale(scale)  # type: ignore[arg-type]


def test_every_writable_format_has_the_one_sink_signature(tmp_path) -> None:
    import inspect

    from upsr.io import registry

    writable = [f.name for f in registry.REGISTRY.values() if f.writable]
    assert sorted(writable) == sorted(_base.WRITE_FORMATS)
    for name in writable:
        impl = registry.module(name)
        params = list(inspect.signature(impl.FrameSink).parameters)
        assert params == ["dest", "temp", "fh", "shape_px", "depth_scale", "n_frames"], name
        assert isinstance(impl.writes_folder(tmp_path / "out"), bool)
    for f in registry.REGISTRY.values():
        impl = registry.module(f.name)
        assert {"start", "stop"} <= set(inspect.signature(impl.frames).parameters), f.name
