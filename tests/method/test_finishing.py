"""What follows the fusion of one output frame (upsr.method.finishing)."""

import numpy as np

from upsr.method.config import UPSRConfig
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
    plain = finish_frame(up, up, low, None, UPSRConfig(scale=r, follow_slopes=False), **kw)
    np.testing.assert_array_equal(plain, up)
    sloped = finish_frame(up, up, low, None, UPSRConfig(scale=r), **kw)
    assert np.abs(np.diff(sloped[4, 4:12])).max() < 25  # the 40 mm steps become a ramp
    filled = finish_frame(up, up, low, None, UPSRConfig(scale=r, fill_holes=True), **kw)
    assert (filled > 0).all()
