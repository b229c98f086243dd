"""upsr.method.splat: the nearest forward-registered sample per high-res pixel (the edge guide
of the fusion)."""

import numpy as np

from upsr.method.splat import splat_nearest, splat_points
from upsr.method.upsampling import upsample_nearest


def test_splat_nearest_places_samples_at_their_registered_centres():
    rng = np.random.default_rng(0)
    lr = rng.uniform(1000, 2000, (1, 5, 6)).astype(np.float32)
    zero = np.zeros((1, 10, 12, 2), np.float32)
    # r = 2, no motion: every high-res pixel is 0.71 px from its own low-res centre only
    np.testing.assert_array_equal(splat_nearest(lr, zero, 2, 1.0), upsample_nearest(lr[0], 2))
    # r = 4: the centres sit 1.5 px from the block corners; beyond the radius nothing is known
    g = splat_nearest(lr, np.zeros((1, 20, 24, 2), np.float32), 4, 1.0)
    assert np.isnan(g[0, 0]) and g[1, 1] == lr[0, 0, 0] and g[2, 2] == lr[0, 0, 0]
    # a second frame moved by +1 px fills in between: its samples land 1 px further right
    two = np.concatenate([lr, lr + 5])
    maps = np.zeros((2, 20, 24, 2), np.float32)
    maps[1, ..., 0] = 1.0
    g2 = splat_nearest(two, maps, 4, 0.75)
    # frame 1's sample centred at (x, y) = (1.5, 1.5) lands at (2.5, 1.5): nearest to (3, 1)
    assert g2[1, 3] == lr[0, 0, 0] + 5 and g2[1, 1] == lr[0, 0, 0]


def test_splat_points_takes_the_nearest_sample_within_the_radius():
    values = np.array([[[1000.0, 2000.0]]], np.float32)  # (1, 1, 2)
    positions = np.array([[[[0.2, 0.0], [2.6, 0.0]]]], np.float32)  # (x, y) in high-res px
    out = splat_points(values, positions, (1, 4), radius_px=0.9)
    # pixel 0 (0.2 away) and 1 (0.8 away) take sample 0; 2 takes sample 1 (0.6 away vs 1.8)
    np.testing.assert_array_equal(out[0, :3], [1000.0, 1000.0, 2000.0])
    assert out[0, 3] == 2000.0  # (0.4 away)
    assert np.isnan(splat_points(values, positions, (1, 4), radius_px=0.1)).all()
