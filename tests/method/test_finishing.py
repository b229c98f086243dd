"""What follows the fusion of one output frame (upsr.method.finishing)."""

import numpy as np
import pytest

import upsr
from upsr.method.config import DeblurConfig, UPSRConfig
from upsr.method.finishing import finish_frame
from upsr.method.mixed import remove_mixed_pixels
from upsr.method.trust import reference_anchor


def _edge_frame():
    """A wall at 1 m left of a wall at 3 m, one mixed pixel on the edge."""
    z = np.full((6, 8), 3000.0, np.float32)
    z[:, :4] = 1000.0
    z[2, 4] = 2000.0
    return z


def test_a_removed_reference_pixel_emptied_after_the_fusion_is_split_never_a_hole():
    r = 2
    measured = _edge_frame()
    reference = remove_mixed_pixels(measured, 100.0)
    anchor = reference_anchor(reference, 5.0, 3.0, 100.0)[0]
    fused = np.repeat(np.repeat(measured, r, axis=0), r, axis=1)
    out = fused.copy()
    out[4:6, 8:10] = 0.0  # the speckle filter emptied the mixed pixel's block
    cfg = UPSRConfig(scale=r, follow_slopes=False)
    kw = dict(edge_mm=100.0, noise_mm=5.0)
    got = finish_frame(out, fused, reference, anchor, cfg, measured=measured, **kw)
    block = got[4:6, 8:10]
    assert (block > 0).all()
    assert set(np.unique(block)) <= {1000.0, 3000.0}  # a neighbour's depth, never a mix
    np.testing.assert_array_equal(np.delete(got, [4, 5], axis=0), np.delete(out, [4, 5], axis=0))
    # without the measured frame the hole stays (nothing says the camera measured there)
    kept = finish_frame(out, fused, reference, anchor, cfg, **kw)
    assert (kept[4:6, 8:10] == 0).all()


def test_follow_slopes_and_fill_holes_are_the_configs_choice():
    r = 2
    low = np.tile(1000.0 + 40.0 * np.arange(8, dtype=np.float32), (6, 1))
    up = np.repeat(np.repeat(low, r, axis=0), r, axis=1)
    up[0:2, 0:2] = 0.0
    kw = dict(edge_mm=100.0, noise_mm=1.0)
    unsmoothed = DeblurConfig(smooth_sigma_mm=None)
    plain = finish_frame(
        up, up, low, None, UPSRConfig(scale=r, follow_slopes=False, deblur=unsmoothed), **kw
    )
    np.testing.assert_array_equal(plain, up)
    smoothed = finish_frame(up, up, low, None, UPSRConfig(scale=r, follow_slopes=False), **kw)
    assert np.abs(smoothed - up).max() > 1.0  # the final smoothing, on by default
    sloped = finish_frame(up, up, low, None, UPSRConfig(scale=r), **kw)
    assert np.abs(np.diff(sloped[4, 4:12])).max() < 25  # the 40 mm steps become a ramp
    filled = finish_frame(up, up, low, None, UPSRConfig(scale=r, fill_holes=True), **kw)
    assert (filled > 0).all()


def test_the_final_smoothing_follows_the_slopes_it_comes_after():
    # a floor at a grazing angle (1/z affine, 60–130 mm per low-res row) with 5 mm of noise,
    # upsampled to its r×r staircase: the blocks follow the slope, then the smoothing removes
    # the noise along it (smoothed first, it measured the staircase's steps as the slope)
    r, (h, w) = 4, (14, 18)
    rng = np.random.default_rng(0)

    def floor(y, x):
        return 1.0 / (1 / 1800.0 - 1.8e-5 * y + 1e-7 * x)

    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    low = (floor(ys, xs) + rng.normal(0.0, 5.0, (h, w))).astype(np.float32)
    yh, xh = (np.mgrid[0 : r * h, 0 : r * w] - (r - 1) / 2) / r
    truth = floor(yh, xh)
    up = np.repeat(np.repeat(low, r, axis=0), r, axis=1)
    out = finish_frame(up, up, low, None, UPSRConfig(scale=r), edge_mm=100.0, noise_mm=5.0)
    inner = (slice(2 * r, -2 * r), slice(2 * r, -2 * r))
    rms = np.sqrt(np.mean((out - truth)[inner] ** 2))
    rms_low = np.sqrt(np.mean((low - floor(ys, xs))[2:-2, 2:-2] ** 2))
    # (0.57: a window of σ = r/2 px averages about three blocks; 1.01 without the smoothing)
    assert rms < 0.75 * rms_low, (rms, rms_low)


@pytest.mark.parametrize(("mode", "bound"), [("windowed", 1.2), ("recursive", 1.75)])
def test_a_static_cameras_steep_floor_keeps_little_more_than_its_temporal_median(mode, bound):
    # a static camera, a floor at a grazing angle (40–210 mm per low-res row), Laplace σ = 10:
    # the output against the truth, relative to the temporal median of the 9 frames at the
    # samples (windowed 1.07×, recursive 1.55×; 1.39× / 2.00× before the final smoothing
    # followed each surface's plane)
    h, w, r, t = 28, 32, 4, 9

    def floor(y, x):
        return 1.0 / (1 / 1800.0 - 1.2e-5 * y + 1e-7 * x)

    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    rng = np.random.default_rng(0)
    low = (floor(ys, xs)[None] + rng.laplace(0, 10 / np.sqrt(2), (t, h, w))).astype(np.float32)
    yh, xh = (np.mgrid[0 : r * h, 0 : r * w] - (r - 1) / 2) / r
    out = upsr.super_resolve(low, r, 9, mode=mode)
    inner = (slice(None), slice(2 * r, -2 * r), slice(2 * r, -2 * r))
    rms = np.sqrt(np.mean((out - floor(yh, xh)[None])[inner] ** 2))
    median = np.median(low, axis=0) - floor(ys, xs)
    rms_median = np.sqrt(np.mean(median[2:-2, 2:-2] ** 2))
    assert rms < bound * rms_median, (rms, rms_median)
