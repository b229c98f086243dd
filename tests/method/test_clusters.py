"""Clusters of like mixes: parts one to two ToF pixels wide (upsr.method.clusters)."""

import numpy as np
import pytest

import upsr
from tests.method._helpers import WALL
from upsr.method.clusters import CLUSTER_SPAN_PX, mixed_clusters
from upsr.method.mixed import remove_mixed_pixels

LEG = 2120.0


def _leg(h=12, w=12, top=4, left=5):
    """A leg in front of the wall: four pixels it fills at ``left`` below a 2×2 cluster of
    like mixes (three quarters of two columns), as a 60×80 ToF sensor sees the realistic
    galloping animal's legs (2318 / 2342 / 2340 / 2331 mm)."""
    z = np.full((h, w), WALL, np.float32)
    z[top + 2 : top + 6, left] = LEG
    z[top : top + 2, left : left + 2] = [[2318.0, 2342.0], [2340.0, 2331.0]]
    return z


def test_a_cluster_of_like_mixes_between_a_leg_and_the_wall_is_mixed():
    z = _leg()
    found = mixed_clusters(z, np.ones(z.shape, bool), 100.0)
    expected = np.zeros(z.shape, bool)
    expected[4:6, 5:7] = True
    np.testing.assert_array_equal(found, expected)
    np.testing.assert_array_equal(remove_mixed_pixels(z, 100.0) <= 0, expected)
    # only among the kept pixels
    assert not mixed_clusters(z, ~expected, 100.0).any()


def test_a_cluster_of_like_mixes_never_reaches_the_output():
    frames = np.repeat(_leg()[None], 5, axis=0)
    kw = dict(deblur=False, noise_mm=2.0, speckle_px=0, remove_mixed=True)
    out = upsr.super_resolve(frames, 4, 5, **kw)
    block = out[2, 16:24, 20:28]
    assert np.all((np.abs(block - LEG) < 100) | (np.abs(block - WALL) < 100))
    assert (np.abs(block - LEG) < 100).any() and (np.abs(block - WALL) < 100).any()
    # without the rule (nor the thin parts') the mixes reach the output
    off = upsr.super_resolve(frames, 4, 5, thin_parts=False, **kw)[2, 16:24, 20:28]
    assert np.any(np.abs(off - 2330) < 20)


@pytest.mark.parametrize(
    "case",
    ["nothing nearer", "at the border", "too wide", "too many", "steep run", "even slope"],
)
def test_what_is_not_a_cluster_of_like_mixes(case):
    z = _leg()
    kw = {}
    if case == "nothing nearer":
        z[6:10, 5] = WALL  # a small part in front of the wall, nearest of all: as measured
    elif case == "at the border":
        z = _leg(top=0)[1:]  # its surface may run on beyond the image
    elif case == "too wide":
        z[4:6, 5 : 5 + CLUSTER_SPAN_PX + 1] = 2330.0
    elif case == "too many":
        # (the default CLUSTER_PX admits every cluster within the span: 3×3 = 9 pixels)
        z[4:7, 5:8] = 2330.0
        z[7:10, 5] = LEG
        assert mixed_clusters(z, np.ones(z.shape, bool), 100.0).any()
        kw = {"max_px": 8}
    elif case == "steep run":
        # a floor seen at a grazing angle: one row of pixels per step beyond the edge threshold
        z = np.repeat((1800.0 + 130.0 * np.arange(12, dtype=np.float32))[:, None], 12, axis=1)
        z[:, :4] = WALL + 500
        z[:, 7:] = 1000.0
    elif case == "even slope":
        # a row of two between steps of 140 / 150 mm above and below it: a slope (as a cluster
        # without the step above)
        z[3:6, 5:7] = np.array([2470.0, 2330.0, 2180.0], np.float32)[:, None]
        assert mixed_clusters(np.where(z == 2470.0, WALL, z), np.ones(z.shape, bool), 100.0).any()
    assert not mixed_clusters(z, np.ones(z.shape, bool), 100.0, **kw).any()


def test_the_clusters_of_an_empty_or_flat_frame():
    assert not mixed_clusters(np.zeros((6, 6), np.float32), np.ones((6, 6), bool), 100.0).any()
    flat = np.full((6, 6), WALL, np.float32)
    assert not mixed_clusters(flat, np.ones((6, 6), bool), 100.0).any()
