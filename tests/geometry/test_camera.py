"""``upsr.geometry.camera``: the pinhole camera's checks and its scaling to the output grid."""

from __future__ import annotations

import math

import pytest

from upsr.errors import InputError
from upsr.geometry.camera import MAX_INTRINSIC_PX, MIN_FOCAL_PX, PinholeCamera


def test_scaled_follows_the_pixel_geometry_of_spec_section_1() -> None:
    cam = PinholeCamera(60.0, 61.0, 31.5, 27.5, 64, 56).scaled(2)
    assert (cam.fx, cam.fy, cam.cx, cam.cy, cam.width, cam.height) == (
        120.0, 122.0, 63.5, 55.5, 128, 112
    )  # fmt: skip


@pytest.mark.parametrize(
    ("fx", "cx", "match"),
    [
        (1e-300, 31.5, "at least"),  # finite, but its points at ±inf
        (0.0, 31.5, "at least"),
        (-60.0, 31.5, "at least"),
        (1e308, 31.5, "beyond"),  # inf once scaled by r
        (60.0, 1e308, "beyond"),
        (math.nan, 31.5, "finite"),
        (60.0, math.inf, "finite"),
    ],
)
def test_absurd_intrinsics_are_refused(fx: float, cx: float, match: str) -> None:
    with pytest.raises(InputError, match=match):
        PinholeCamera(fx, 60.0, cx, 27.5, 64, 56)


def test_the_bounds_themselves_are_cameras() -> None:
    PinholeCamera(MIN_FOCAL_PX, MAX_INTRINSIC_PX, -MAX_INTRINSIC_PX, 0.0, 1, 1)
