"""The other surfaces a sample may show at a depth edge (upsr.method.alternatives)."""

import numpy as np

from upsr.method.alternatives import alternatives_on_grid, side_of_centre, surface_alternatives

WALL = 3000.0


def test_alternatives_are_on_the_side_of_their_neighbour_only():
    np.testing.assert_array_equal(side_of_centre(8, 4), [-1, -1, 1, 1, -1, -1, 1, 1])
    np.testing.assert_array_equal(side_of_centre(6, 3), [-1, 0, 1, -1, 0, 1])
    anchor = np.full((7, 9), WALL, np.float32)
    anchor[:, :4] = 1000.0  # a wide foreground: columns 0..3
    tol = np.full_like(anchor, 10.0)
    near, near_tol, far, far_tol = surface_alternatives(anchor, tol, 100.0)
    assert near.shape == (3, 3, 7, 9)
    # the foreground's edge column 3: the wall competes only on its right side (sx = +1)
    assert (far[:, 2, :, 3] == WALL).all() and (far[:, :2, :, 3] == 0).all()
    assert (far_tol[:, 2, :, 3] == 10.0).all()
    assert (near[:, 0, :, 4] == 1000.0).all() and (near[:, 1:, :, 4] == 0).all()
    assert (near[1, 1] == 0).all() and (far[1, 1] == 0).all()  # never at the centre
    grid_near, _, grid_far, _ = alternatives_on_grid((near, near_tol, far, far_tol), 4)
    assert grid_far.shape == (28, 36)
    np.testing.assert_array_equal(grid_far[:, 12:16] == WALL, np.tile([0, 0, 1, 1], (28, 1)) == 1)
    np.testing.assert_array_equal(
        grid_near[:, 16:20] == 1000.0, np.tile([1, 1, 0, 0], (28, 1)) == 1
    )
