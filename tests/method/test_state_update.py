"""The recursive mode's state update (one frame): restarts, holes, the trust rules."""

import numpy as np

from upsr.method.state_update import recursive_update
from upsr.method.trust import reference_anchor


def test_a_restart_is_the_mean_of_the_measurement_and_its_anchor_unless_it_is_an_outlier():
    """The anchor alone (a median of up to 9 samples) keeps the error of a quantised sensor's
    steps or of a slope's crease; the measurement alone, its noise; the measurement's pull is
    limited to τ/3, about σ (docs/notes/recursive.md)."""
    meas = np.full((8, 8), 2000.0, np.float32)
    meas[2, 2] = 2006.0  # well within the tolerance of its anchor (k·σ = 30 mm)
    meas[2, 5] = 2025.0  # within it, beyond τ/3
    meas[5, 5] = 2060.0  # beyond it: an outlier
    anchor, tol = reference_anchor(meas, 10.0, 3.0, 100.0, own_surface="always")
    assert anchor[2, 2] == anchor[2, 5] == anchor[5, 5] == 2000.0
    assert 18.0 <= tol[2, 2] and 25.0 <= tol[2, 5] < 75.0 and tol[5, 5] < 60.0
    r = 2
    empty = np.zeros((8 * r, 8 * r), np.float32)
    flow = np.zeros((8 * r, 8 * r, 2), np.float32)
    depth, count = recursive_update(
        empty, empty, flow, meas, anchor, tol, scale=r, cap=9.0, sigma_mm=10.0
    )
    np.testing.assert_allclose(depth[4:6, 4:6], 2003.0)  # the mean of the two
    np.testing.assert_allclose(depth[4:6, 10:12], 2000.0 + tol[2, 5] / 6, rtol=1e-6)
    np.testing.assert_allclose(depth[10:12, 10:12], 2000.0)
    np.testing.assert_allclose(depth[:2, :2], 2000.0)
    assert (count[meas.repeat(r, 0).repeat(r, 1) > 0] == 2.0).all()


def test_a_hole_keeps_the_state_only_where_its_surface_is_seen_around_it():
    """A leg that moved away from where nothing returns (no wall behind the animal) leaves no
    ghost; a dropout inside a surface and a hole inside measured surroundings (a removed
    mixed pixel, a projector shadow: ``enclosed``) keep the state."""
    r, h, w = 2, 12, 24
    depth = np.zeros((h * r, w * r), np.float32)
    depth[:, : 4 * r] = 2500.0  # a wall on the left
    depth[:, 17 * r : 18 * r] = 2200.0  # the far leg, seen at column 17 before
    count = np.where(depth > 0, np.float32(4.0), np.float32(0.0))
    meas = np.zeros((h, w), np.float32)
    meas[:, :4] = 2500.0
    meas[5, 1] = 0.0  # a dropout inside the wall
    meas[:, 19] = 1800.0  # the near leg now beside it; the far leg moved on, out of view,
    # and nothing returns where it was (the state, farther than the near leg, would be kept
    # as what a shadow hides)
    anchor, tol = reference_anchor(meas, 5.0, 3.0, 100.0, own_surface="always")
    flow = np.zeros((h * r, w * r, 2), np.float32)
    args = (depth, count, flow, meas, anchor, tol)
    kw = {"scale": r, "cap": 9.0, "sigma_mm": 5.0, "radial_radius_px": None}
    out, n = recursive_update(*args, **kw)
    assert (out[:, 17 * r : 18 * r] == 0).all() and (n[:, 17 * r : 18 * r] == 0).all()  # no ghost
    np.testing.assert_allclose(out[5 * r : 6 * r, r : 2 * r], 2500.0)  # the dropout
    assert (n[5 * r : 6 * r, r : 2 * r] == 2.0).all()
    # the far leg's column enclosed (a removed mixed pixel of the frame): its state stays
    enclosed = np.zeros((h, w), np.bool_)
    enclosed[:, 17] = True
    holes = np.zeros((h, w), np.float32)  # (as the engine gives them: not holes)
    out, _ = recursive_update(*args, holes=holes, enclosed=enclosed, **kw)
    np.testing.assert_allclose(out[:, 17 * r : 18 * r], 2200.0)


def test_a_foreground_the_state_carried_into_a_background_block_is_not_kept():
    """A box's edge in the state two pixels inside a block whose sample, and every sample
    beside it but the box's, measure the wall (the flow of a camera approaching fast drags the
    box's depth over the wall beside it): the block is the wall again, not the box grown by
    half a block, frame after frame."""
    r = 4
    low = np.full((4, 4), 2000.0, np.float32)
    low[:, 0] = 1000.0  # the box: low-res column 0, high-res columns 0-3
    depth = np.full((16, 16), 2000.0, np.float32)
    depth[:, :6] = 1000.0  # the state's box reaches two pixels into column 1's block
    count = np.full((16, 16), 5.0, np.float32)
    anchor, tol = reference_anchor(low, 5.0, 3.0, 100.0)
    flow = np.zeros((16, 16, 2), np.float32)
    new, _ = recursive_update(
        depth, count, flow, low, anchor, tol, scale=r, cap=9.0, sigma_mm=5.0,
        radial_radius_px=None,
    )  # fmt: skip
    np.testing.assert_allclose(new[:, 4:], 2000.0, atol=1e-3)
    np.testing.assert_allclose(new[:, :4], 1000.0, atol=1e-3)


def test_a_noise_outlier_of_the_frame_is_outvoted_by_the_state_until_it_persists():
    """A noise outlier of the frame (``outliers``: it and the depth of the surface around it)
    leaves a state on that surface there, its count halved, as a window's other frames
    outvote it; a state that holds the outlier's surface, or another surface (a body that
    arrived), is updated as without it; one that persists restarts the pixel once the count
    has run out; ``kept`` says where the state won."""
    r, h, w = 2, 6, 6
    meas = np.full((h, w), 2000.0, np.float32)
    meas[2, 2] = 2060.0  # an outlier the state does not hold
    meas[3, 4] = 1950.0  # an outlier the state holds (a small object it followed)
    meas[4, 1] = 2055.0  # an outlier where the state has another surface (the wall behind)
    anchor, tol = reference_anchor(meas, 10.0, 3.0, 100.0, own_surface="always")
    depth = np.full((h * r, w * r), 2000.0, np.float32)
    depth[6:8, 8:10] = 1952.0
    depth[8:10, 2:4] = 2800.0
    count = np.full((h * r, w * r), 6.0, np.float32)
    around, limit = np.zeros((h, w), np.float32), np.zeros((h, w), np.float32)
    for i, j in ((2, 2), (3, 4), (4, 1)):
        around[i, j], limit[i, j] = 2000.0, 35.0
    outliers = (around, limit)
    flow = np.zeros((h * r, w * r, 2), np.float32)
    kw = {"scale": r, "cap": 9.0, "sigma_mm": 10.0, "radial_radius_px": None}
    kept = np.ones((h, w), np.bool_)
    new, n = recursive_update(
        depth, count, flow, meas, anchor, tol, outliers=outliers, kept=kept, **kw
    )
    np.testing.assert_allclose(new[4:6, 4:6], 2000.0)
    np.testing.assert_allclose(n[4:6, 4:6], 3.0)
    assert kept[2, 2] and kept.sum() == 1
    # without them the outlier is averaged in (+60/7 mm); where the state holds the
    # outlier's surface or another one, the update is the same with and without them
    plain, plain_n = recursive_update(depth, count, flow, meas, anchor, tol, **kw)
    np.testing.assert_allclose(plain[4:6, 4:6], 2000.0 + 60.0 / 7.0, rtol=1e-6)
    for block in (np.s_[6:8, 8:10], np.s_[8:10, 2:4]):
        np.testing.assert_array_equal(new[block], plain[block])
        np.testing.assert_array_equal(n[block], plain_n[block])
    # it persists: the count halves frame after frame, then the pixel restarts from it
    new, n = recursive_update(new, n, flow, meas, anchor, tol, outliers=outliers, **kw)
    np.testing.assert_allclose(n[4:6, 4:6], 1.5, rtol=1e-4)
    np.testing.assert_allclose(new[4:6, 4:6], 2000.0)
    new, n = recursive_update(new, n, flow, meas, anchor, tol, outliers=outliers, **kw)
    np.testing.assert_allclose(new[4:6, 4:6], 2060.0)
    np.testing.assert_allclose(n[4:6, 4:6], 1.0)


def _drifting_body(
    drift_mm: float,
    signs: bool,
    frames: int = 30,
    seed: int = 0,
    sigma: float = 10.0,
    body_mm: float = 1500.0,
    last: int = 20,
) -> float:
    """The state of a body at ``body_mm`` in front of a static wall 500 mm behind it, which
    moves ``drift_mm`` along the ray every frame with zero flow (it comes nearer without
    moving sideways), Laplacian noise of σ = ``sigma`` mm: the mean error of the state on the
    body's interior against the truth over the ``last`` frames (positive: it lags behind)."""
    rng = np.random.default_rng(seed)
    r, h, w = 2, 32, 32
    flow = np.zeros((h * r, w * r, 2), np.float32)
    depth = count = np.zeros((h * r, w * r), np.float32)
    state_signs = np.zeros((h, w), np.int8) if signs else None
    errors = []
    for t in range(frames):
        truth = np.full((h, w), body_mm + 500.0, np.float32)
        truth[10:22, 10:22] = body_mm - drift_mm * t
        meas = (truth + rng.laplace(0.0, sigma / np.sqrt(2.0), (h, w))).astype(np.float32)
        anchor, tol = reference_anchor(meas, sigma, 3.0, 100.0, own_surface="always")
        depth, count = recursive_update(
            depth, count, flow, meas, anchor, tol, scale=r, cap=9.0, sigma_mm=sigma,
            offset_signs=state_signs,
        )  # fmt: skip
        if t >= frames - last:
            body = slice(12 * r, 20 * r)
            errors.append(float(np.mean(depth[body, body])) - float(truth[15, 15]))
    return float(np.mean(errors))


def test_an_offset_that_comes_twice_the_same_way_is_kept_from_two_standard_errors():
    """A body that comes nearer by less than the 4 standard errors of an unmoved pixel's
    offset per frame leaves the state behind until its lag is significant; with the signs of
    the previous frame's offsets an offset of 2 standard errors that goes the same way twice
    in a row is kept (STATE_CONFIRMED_SIGNIFICANCE): the lag shrinks, and where nothing
    moves the state stays the running mean of the samples."""
    # the offset's standard error: 1.2533·√2·0.75σ/5 ≈ 2.7 mm; 1 mm per frame lies far
    # below its 4 standard errors
    for seed in range(3):
        lag = _drifting_body(1.0, signs=False, seed=seed)
        assert lag > 4.5
        assert _drifting_body(1.0, signs=True, seed=seed) < 0.65 * lag
        still = _drifting_body(0.0, signs=False, seed=seed)
        assert abs(still) < 0.3
        assert _drifting_body(0.0, signs=True, seed=seed) == still


def test_an_offset_near_the_edge_threshold_is_measured_again_around_itself():
    """A body 90 mm nearer per frame under σ = 30 mm: its differences from the state spread
    beyond the edge threshold (100 mm), within which the offset is measured, and the offset
    fell short: measured again on the state less the first offset (where it lies beyond half
    the threshold), the state keeps up with the body."""
    for seed in range(3):
        lag = _drifting_body(90.0, True, frames=14, seed=seed, sigma=30.0, body_mm=3000.0, last=9)
        assert abs(lag) < 6.0  # (24–31 mm behind when measured once)
