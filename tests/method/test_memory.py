"""How many frames each pixel's recursive state may summarise (upsr.method.memory)."""

import itertools

import numpy as np
import pytest

import upsr
from upsr.method.memory import (
    REGISTRATION_ERROR_PX,
    innovation_caps,
    level_to_reference,
    state_caps,
)
from upsr.method.state_update import recursive_update
from upsr.method.trust import reference_anchor


def _ramp(slope_mm_per_px, shape=(12, 16), base=2000.0):
    xs = np.arange(shape[1], dtype=np.float32)
    return np.broadcast_to(base + slope_mm_per_px * xs, shape).astype(np.float32).copy()


def _caps(z, sigma, k=3.0, cap=9.0, **kw):
    anchor, tol = reference_anchor(z, sigma, k, 1000.0)
    return state_caps(anchor, tol, cap, sigma, k, **kw)[2:-2, 2:-2]


def test_a_flat_surface_keeps_the_whole_window():
    rng = np.random.default_rng(0)
    noisy = _ramp(0.0) + rng.normal(0, 10, (12, 16)).astype(np.float32)
    assert (_caps(noisy, 10.0) == 9.0).mean() > 0.9
    assert (_caps(_ramp(0.0), 0.0) == 9.0).all()  # noise-free and flat: nothing to lose


@pytest.mark.parametrize("sigma", [0.0, 10.0])
def test_a_steep_slope_relies_on_the_current_frame(sigma):
    # 400 mm per low-res pixel: a quarter pixel of registration error is 100 mm, 10σ
    caps = _caps(_ramp(400.0), sigma)
    np.testing.assert_allclose(caps, 1.0, atol=0.02)


def test_the_cap_falls_with_the_slope_and_rises_with_the_noise():
    slopes = [0.0, 20.0, 60.0, 120.0, 240.0]
    caps = [float(np.median(_caps(_ramp(g), 10.0))) for g in slopes]
    assert caps[0] == 9.0
    assert all(a >= b for a, b in itertools.pairwise(caps)), caps
    assert caps[-1] < 2.0 < caps[1]
    quiet, loud = (float(np.median(_caps(_ramp(120.0), s))) for s in (5.0, 30.0))
    assert quiet < loud


def test_the_cap_is_the_steady_state_of_the_kalman_filter():
    """n = σ²/v with v the fixed point of predict (v + q) then update (v·σ²/(v + σ²))."""
    sigma, k, g = 10.0, 3.0, 100.0
    tol = np.full((1, 1), k * sigma + 2.0 * sigma + g, np.float32)  # relief: g + 2σ of noise
    anchor = np.full((1, 1), 2000.0, np.float32)
    n = float(state_caps(anchor, tol, 1e6, sigma, k)[0, 0])
    q, v = (REGISTRATION_ERROR_PX * g) ** 2, sigma**2
    for _ in range(1000):
        p = v + q
        v = p * sigma**2 / (p + sigma**2)
    assert n == pytest.approx(sigma**2 / v, rel=1e-4)


def test_no_trust_test_or_no_registration_error_keeps_the_cap():
    anchor, tol = reference_anchor(_ramp(400.0), 10.0, 3.0, 1000.0)
    assert (state_caps(anchor, tol, 9.0, 10.0, 0.0) == 9.0).all()
    assert (state_caps(anchor, tol, 9.0, 10.0, 3.0, registration_px=0.0) == 9.0).all()


def test_the_update_never_counts_beyond_the_pixels_cap():
    r, h, w = 2, 8, 10
    meas = np.full((h, w), 2000.0, np.float32)
    depth = np.full((h * r, w * r), 2000.0, np.float32)
    count = np.full_like(depth, 8.0)
    caps = np.full((h, w), 9.0, np.float32)
    caps[:, : w // 2] = 1.0
    anchor, tol = reference_anchor(meas, 5.0, 3.0, 100.0)
    flow = np.zeros((h, w, 2), np.float32)
    _, n = recursive_update(depth, count, flow, meas, anchor, tol, scale=r, cap=caps)
    assert (n[:, :w] == 1.0).all()
    assert (n[:, w:] == 9.0).all()


def test_a_slopes_state_that_strays_from_the_frames_summarises_fewer_frames():
    """innovation_caps: where the registered state of a slope differs from the frame by 3σ
    (a flow that is off there), the cap falls to about one frame; where it differs by what a
    state of 9 frames and the noise allow, off the slope, by the offset it was moved by, or
    without a state, the caps stay."""
    rng = np.random.default_rng(0)
    h, w, sigma = 12, 16, 10.0
    meas = (2000.0 + rng.normal(0, sigma, (h, w))).astype(np.float32)
    count = np.full((h, w), 9.0, np.float32)
    caps = np.full((h, w), 9.0, np.float32)
    sloped = np.zeros((h, w), bool)
    sloped[:, : w // 2] = True
    none = np.zeros((h, w), np.float32)

    def caps_of(registered, offsets=none):
        return innovation_caps(caps, registered, meas, offsets, count, sloped, sigma)

    agreeing = (meas + rng.normal(0, sigma / 3, (h, w))).astype(np.float32)
    np.testing.assert_array_equal(caps_of(agreeing), caps)
    stray = (meas + rng.normal(0, 3 * sigma, (h, w))).astype(np.float32)
    out = caps_of(stray)
    assert (out[2:-2, 2 : w // 2 - 2] < 2.0).all()
    np.testing.assert_array_equal(out[:, w // 2 :], 9.0)
    np.testing.assert_array_equal(caps_of(agreeing + 50.0, none + 50.0), caps)
    np.testing.assert_array_equal(caps_of(none), caps)


def _sliding_ramp(slope_mm_per_px, speed_px, sigma, *, r=2, t=10, shape=(16, 24)):
    """A slanted floor seen by a camera moving sideways: truth (t, r·h, r·w), ToF-like
    low-res frames (the mean of each r×r block) with Gaussian noise."""
    h, w = shape
    xs = np.arange(w * r, dtype=np.float32)
    rows = [2000.0 + slope_mm_per_px * (xs + 0.5 - speed_px * r * k) / r for k in range(t)]
    truth = np.stack([np.broadcast_to(row, (h * r, w * r)) for row in rows]).astype(np.float32)
    low = truth.reshape(t, h, r, w, r).mean(axis=(2, 4))
    low += np.random.default_rng(0).normal(0, sigma, low.shape).astype(np.float32)
    return truth, low


@pytest.mark.parametrize(("sigma", "most_mm"), [(0.0, 1.0), (3.0, 9.0)])
def test_a_slope_seen_by_a_moving_camera_does_not_lag(sigma, most_mm):
    """80 mm per low-res pixel, 0.7 px per frame: the state registered with a flow that is
    never exact carried the slope's old depths along (rms 13.4 mm without noise, 11.6 at
    σ = 3, with the whole window as every pixel's cap); nearest: 20 mm."""
    r = 2
    truth, low = _sliding_ramp(80.0, 0.7, sigma, r=r)
    out = np.stack(list(upsr.UPSR(r, 9, mode="recursive").process(low)))
    rms = float(np.sqrt(((out - truth)[3:, 4:-4, 4:-4] ** 2).mean()))
    nearest = np.repeat(np.repeat(low, r, axis=1), r, axis=2)
    assert rms < most_mm
    assert rms < 0.5 * float(np.sqrt(((nearest - truth)[3:, 4:-4, 4:-4] ** 2).mean()))


def _level(fused, reference, anchor_z=None, *, n=9, sigma=0.0, k=3.0, r=2, edge=100.0):
    anchor, tol = reference_anchor(reference if anchor_z is None else anchor_z, sigma, k, edge)
    cfg = upsr.UPSRConfig(scale=r, n_frames=n, trust_k=k)
    caps = state_caps(anchor, tol, float(n), sigma, k)
    return level_to_reference(fused, reference, caps, cfg, edge_mm=edge)


def test_a_steep_blocks_level_becomes_the_references_and_its_shape_stays():
    """Noise-free, 60 mm per low-res pixel: every block's mean moves onto the reference's
    sample (a fusion whose other frames were misregistered: +20 mm), the detail inside the
    block (the other frames' sub-pixel samples) is kept."""
    reference = _ramp(60.0, shape=(6, 8))
    detail = np.tile(np.array([[-15.0, 15.0], [-15.0, 15.0]], np.float32), (6, 8))
    fused = np.repeat(np.repeat(reference, 2, axis=0), 2, axis=1) + 20.0 + detail
    out = _level(fused, reference)
    blocks = out.reshape(6, 2, 8, 2).mean(axis=(1, 3))
    np.testing.assert_allclose(blocks, reference, atol=1e-3)
    np.testing.assert_allclose(out - np.repeat(np.repeat(blocks, 2, 0), 2, 1), detail, atol=1e-3)


def test_flat_blocks_edges_holes_and_unmeasured_pixels_keep_the_fusions_level():
    reference = _ramp(0.0, shape=(6, 8))
    fused = np.repeat(np.repeat(reference, 2, axis=0), 2, axis=1) + 5.0
    np.testing.assert_array_equal(_level(fused, reference, sigma=3.0), fused)  # flat: cap N
    steep = _ramp(60.0, shape=(6, 8))
    up = np.repeat(np.repeat(steep, 2, axis=0), 2, axis=1) + 20.0
    across = up.copy()
    across[4:6, 4:6] = [[500.0, 500.0], [up[4, 4], up[4, 4]]]  # a block across a depth edge
    across[8, 8] = 0.0  # a block with a hole
    measured = steep.copy()
    measured[0, 0] = 0.0  # no measurement
    measured[0, 1] = -1.0  # a removed (mixed) pixel
    out = _level(across, measured, anchor_z=steep)
    for i, j in ((2, 2), (4, 4), (0, 0), (0, 1)):
        np.testing.assert_array_equal(out[2 * i : 2 * i + 2, 2 * j : 2 * j + 2],
                                      across[2 * i : 2 * i + 2, 2 * j : 2 * j + 2])  # fmt: skip
    assert out[8, 8] == 0.0  # 0 stays 0
    assert abs(out[2:4, 6:8].mean() - steep[1, 3]) < 1e-3  # a full block on the slope moves


def test_no_trust_test_or_a_single_frame_moves_nothing():
    reference = _ramp(60.0, shape=(6, 8))
    fused = np.repeat(np.repeat(reference, 2, axis=0), 2, axis=1) + 20.0
    anchor, tol = reference_anchor(reference, 0.0, 3.0, 100.0)
    for cfg in (
        upsr.UPSRConfig(scale=2, n_frames=9, trust_k=None),
        upsr.UPSRConfig(scale=2, n_frames=1),
    ):
        caps = state_caps(anchor, tol, float(cfg.n_frames), 0.0, 3.0)
        out = level_to_reference(fused, reference, caps, cfg, edge_mm=100.0)
        np.testing.assert_array_equal(out, fused)


def test_a_camera_walking_towards_box_sides_without_noise_is_not_worse_than_its_input():
    """The realistic approaching camera, noise-free: the box sides at grazing angles whose
    fused level the zoomed frames moved (surface rmse 10.1 mm against nearest's 9.4 without
    the rule) take the reference's level."""
    from upsr.research.metrics import evaluate
    from upsr.research.synth.realistic import degrade, make_realistic

    video = make_realistic("toward_wall", (56, 64), scale=4, n_frames=9)
    low = degrade(video, "laplace", np.random.default_rng(0), sigma_mm=0.0)
    out = upsr.super_resolve(low, 4, 9, workers=0)
    nearest = np.repeat(np.repeat(low, 4, axis=1), 4, axis=2)
    ours = evaluate(out, video.truth, 4)["surface_rmse"]
    assert ours < evaluate(nearest, video.truth, 4)["surface_rmse"]


def test_frames_beyond_a_moving_slopes_reach_abstain():
    """A steep slope (cap n* ≈ 1) that moved: the frames more than REACH_MIN_FRAMES from the
    reference (an off-centre window at the end of a clip) abstain there; the same slope
    static, a flat surface that moved (n* = N), or no trust test: none abstains."""
    from upsr.method.memory import REACH_MIN_FRAMES, beyond_reach
    from upsr.method.trust import reference_anchor

    n, h, w = 9, 6, 8
    steep = np.tile(1000.0 + 400.0 * np.arange(w, dtype=np.float32), (h, 1))
    flat = np.full((h, w), 2000.0, np.float32)
    moved = np.zeros((n, h, w, 2), np.float32)
    moved[..., 0] = 2.0  # 2 flow px = 1 low-res px at grid scale 2
    ref = n - 1
    anchor, tol = reference_anchor(steep, 10.0, 3.0, 1000.0)
    caps = state_caps(anchor, tol, float(n), 10.0, 3.0)
    out = beyond_reach(moved, caps, ref, grid_scale=2.0)
    distance = np.abs(np.arange(n) - ref)
    assert out[distance > REACH_MIN_FRAMES].all()
    assert not out[distance <= REACH_MIN_FRAMES].any()
    assert not beyond_reach(np.zeros_like(moved), caps, ref, grid_scale=2.0).any()
    a_flat, t_flat = reference_anchor(flat, 10.0, 3.0, 1000.0)
    flat_caps = state_caps(a_flat, t_flat, float(n), 10.0, 3.0)
    assert not beyond_reach(moved, flat_caps, ref, grid_scale=2.0).any()
    no_test = state_caps(anchor, tol, float(n), 10.0, 0.0)  # k = 0: no trust test
    assert not beyond_reach(moved, no_test, ref, grid_scale=2.0).any()


def test_a_moving_slopes_state_summarises_about_half_its_frames():
    """moving_caps: where the pixel moved (beyond MOVED_PX) and n* < N, the cap becomes
    min(n*, max(REACH_MIN_FRAMES, ⌊(n* − 1)/2⌋)), and a flat surface's (n* = N) becomes
    MOVING_STATE_FRAMES; pixels that did not move and motions below MOVED_PX keep their cap."""
    from upsr.method.memory import MOVED_PX, MOVING_STATE_FRAMES, moving_caps

    caps = np.array([[9.0, 7.0, 5.0, 3.0, 1.5]], np.float32)
    flow = np.zeros((2, 10, 2), np.float32)  # grid scale 2
    flow[..., 0] = 2.0  # one low-res px
    assert 3 < MOVING_STATE_FRAMES < 9
    want = [[MOVING_STATE_FRAMES, 3, 2, 2, 1.5]]
    np.testing.assert_array_equal(moving_caps(caps, flow, 9, grid_scale=2.0), want)
    np.testing.assert_array_equal(moving_caps(caps, np.zeros_like(flow), 9, grid_scale=2.0), caps)
    flow[..., 0] = 2.0 * 0.9 * MOVED_PX
    np.testing.assert_array_equal(moving_caps(caps, flow, 9, grid_scale=2.0), caps)
    flow[:, 4:, 1] = -2.0  # the motion's length counts, in either direction
    assert moving_caps(caps, flow, 9, grid_scale=2.0)[0, 2] == 2.0


def test_the_motion_at_the_centres_is_read_from_centres_when_given():
    """beyond_reach and moving_caps take the maps at the pixel centres the caller computed
    once (the recursive and windowed engines share them with the radial test): the same
    result as from the maps, and the centres, not the maps, are what they read."""
    from upsr.method.consistency import maps_at_centres
    from upsr.method.memory import beyond_reach, moving_caps

    caps = np.array([[9.0, 7.0, 5.0, 3.0, 1.5]], np.float32)
    flow = np.zeros((1, 2, 10, 2), np.float32)
    flow[..., 0] = 2.0
    at = maps_at_centres(flow, caps.shape)
    np.testing.assert_array_equal(
        moving_caps(caps, flow[0], 9, grid_scale=2.0, centres=at),
        moving_caps(caps, flow[0], 9, grid_scale=2.0),
    )
    still = np.zeros_like(at)
    np.testing.assert_array_equal(
        moving_caps(caps, flow[0], 9, grid_scale=2.0, centres=still), caps
    )
    maps = np.repeat(flow, 9, axis=0)
    at9 = maps_at_centres(maps, caps.shape)
    far = beyond_reach(maps, caps, 8, grid_scale=2.0)
    assert far.any()
    np.testing.assert_array_equal(beyond_reach(maps, caps, 8, grid_scale=2.0, centres=at9), far)
    assert not beyond_reach(maps, caps, 8, grid_scale=2.0, centres=np.zeros_like(at9)).any()
