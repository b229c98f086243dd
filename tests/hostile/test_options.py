"""Every numeric option value gives a valid config or one InputError line: never
OverflowError/TypeError, and every option has an upper bound."""

from __future__ import annotations

import dataclasses
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from upsr.errors import InputError
from upsr.method.config import DeblurConfig, UPSRConfig

from .conftest import assert_one_line

_NUMERIC = [
    f.name
    for f in dataclasses.fields(UPSRConfig)
    if f.name not in ("flow", "flow_preset", "refine_preset", "refine", "deblur", "depth_range_mm")
]
_DEBLUR = [f.name for f in dataclasses.fields(DeblurConfig) if f.name not in ("enabled", "blur")]

hostile = st.one_of(
    st.integers(),
    st.integers(min_value=10**15, max_value=10**400),
    st.integers(max_value=-1),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([math.inf, -math.inf, math.nan, 1e308, 10**20, -5, 0, 0.0, 1, 2, True]),
    st.text(max_size=5),
    st.none(),
)


def _build(name: str, value: object, deblur: bool) -> None:
    if deblur:
        UPSRConfig(deblur=DeblurConfig(**{name: value}))
    else:
        UPSRConfig(**{name: value})


@settings(max_examples=400, deadline=None)
@given(st.sampled_from([(n, False) for n in _NUMERIC] + [(n, True) for n in _DEBLUR]), hostile)
def test_any_option_value_is_valid_or_input_error(option: tuple[str, bool], value: object) -> None:
    name, deblur = option
    try:
        _build(name, value, deblur)
    except InputError as e:
        msg = str(e)
        assert "\n" not in msg and len(msg) <= 200, msg


@settings(max_examples=100, deadline=None)
@given(hostile, hostile)
def test_depth_range_values(near: object, far: object) -> None:
    try:
        UPSRConfig(depth_range_mm=(near, far))  # type: ignore[arg-type]
    except InputError:
        pass


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"scale": 10**9}, "scale r"),
        ({"scale": 150}, "scale r"),
        ({"scale": 17}, "scale r"),
        ({"speckle_px": 10**20}, "speckle_px"),
        ({"n_frames": 10**6}, "n_frames"),
        ({"prefilter_sigma_px": 1e6}, "prefilter_sigma_px"),
        ({"edge_mm": math.nan}, "edge_mm"),
        ({"splat_radius_px": 1e9}, "splat_radius_px"),
    ],
)
def test_upper_bounds(kwargs: dict[str, object], match: str) -> None:
    with pytest.raises(InputError, match=match) as e:
        UPSRConfig(**kwargs)  # type: ignore[arg-type]
    assert_one_line(e)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"radius_px": 100000}, "radius_px"),
        ({"radius_px": 11}, "radius_px"),
        ({"iterations": 10**9}, "iterations"),
        ({"blur_sigma_px": 1e30}, "blur_sigma_px"),
        ({"lam": 10**400}, "lam"),
        ({"smooth_sigma_px": math.inf}, "smooth_sigma_px"),
    ],
)
def test_deblur_upper_bounds(kwargs: dict[str, object], match: str) -> None:
    with pytest.raises(InputError, match=match) as e:
        DeblurConfig(**kwargs)  # type: ignore[arg-type]
    assert_one_line(e)


def test_bounds_keep_the_defaults_and_the_documented_range() -> None:
    UPSRConfig()
    UPSRConfig(scale=16, n_frames=256, speckle_px=0, deblur=DeblurConfig(radius_px=10))
    cfg = UPSRConfig.from_options(4, 9, deblur_radius_px=3, speckle_px=10**6)
    assert cfg.deblur.radius_px == 3 and cfg.speckle_px == 10**6
