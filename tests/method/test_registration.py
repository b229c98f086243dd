import numpy as np
import pytest

from upsr.method.registration import (
    compose_flows,
    cumulative_flows,
    flows_to_reference,
    identity_grid,
    sample_offsets,
    warp_nearest,
)

H, W = 64, 80


def _field(kind, xs, ys):
    """Smooth non-rigid motion fields (px)."""
    if kind == "swirl":
        return np.stack([3 * np.sin(ys / 9.0) + 0.05 * (xs - 40), 2.5 * np.cos(xs / 11.0)], -1)
    return np.stack([2 + 2 * np.cos(ys / 7.0), -1.5 + 2 * np.sin(xs / 8.0)], -1)


def test_composition_matches_nonrigid_motion_better_than_addition():
    xs, ys = identity_grid(H, W)
    f1 = _field("swirl", xs, ys).astype(np.float32)  # a -> b on a's grid
    f2 = _field("wave", xs, ys).astype(np.float32)  # b -> c on b's grid
    # exact a -> c: follow f1, then evaluate the analytic f2 at the displaced position
    qx, qy = xs + f1[..., 0], ys + f1[..., 1]
    truth = f1 + _field("wave", qx, qy)
    inner = (slice(8, -8), slice(8, -8))
    err_comp = np.hypot(*(compose_flows(f1, f2) - truth)[inner].transpose(2, 0, 1)).mean()
    # (the naive chaining: both read at the same pixel, wrong for non-rigid motion)
    err_add = np.hypot(*(f1 + f2 - truth)[inner].transpose(2, 0, 1)).mean()
    assert err_comp < 0.05
    assert err_add > 10 * err_comp


def test_warp_nearest_integer_shift_and_outside():
    img = np.arange(H * W, dtype=np.float32).reshape(H, W) + 1
    flow = np.zeros((H, W, 2), np.float32)
    flow[..., 0] = 2.3  # rounds to 2 px
    out = warp_nearest(img, flow)
    np.testing.assert_array_equal(out[:, :-2], img[:, 2:])
    assert np.isnan(out[:, -2:]).all()
    assert (warp_nearest(img, flow, fill=0)[:, -2:] == 0).all()


def test_cumulative_flows_of_constant_motion_add_up():
    n, ref = 5, 2
    step = np.zeros((H, W, 2), np.float32)
    step[..., 0] = 1.25
    forward = [step] * n
    backward = [-step] * n
    maps = cumulative_flows(ref, backward, forward, (H, W))
    for j, m in enumerate(maps):
        np.testing.assert_allclose(m[20:40, 20:40, 0], 1.25 * (j - ref), atol=1e-5)
    back = flows_to_reference(ref, backward, forward, (H, W))
    for m, b in zip(maps, back, strict=True):
        round_trip = compose_flows(m, b)  # reference -> frame -> reference
        assert np.abs(round_trip[10:50, 10:60]).max() < 1e-4


def test_refinement_removes_drift():
    # frames of a textured pattern moving by 1 px per frame; the consecutive flows given to the
    # chain are biased by +0.3 px; eq. 19 re-estimation measures and removes the accumulated drift
    from upsr.method.motion import make_flow_backend

    rng = np.random.default_rng(0)
    base = (rng.uniform(0, 255, (H // 4, W // 4))).astype(np.float32)
    import cv2

    base = cv2.resize(base, (W + 20, H), interpolation=cv2.INTER_CUBIC)
    frames = [np.clip(base[:, 10 - k : 10 - k + W], 0, 255).astype(np.uint8) for k in range(-2, 3)]
    biased = np.zeros((H, W, 2), np.float32)
    biased[..., 0] = 1.3  # true motion frame j -> j+1 is +1 px in x
    fwd = [biased] * 5
    bwd = [-biased] * 5
    flow = make_flow_backend("dis", "medium")
    plain = cumulative_flows(2, bwd, fwd, (H, W))
    refined = cumulative_flows(2, bwd, fwd, (H, W), refine=flow, guides=frames)
    inner = (slice(10, -10), slice(15, -15), 0)
    for j in (0, 4):
        truth = j - 2
        assert abs(np.median(plain[j][inner]) - truth) == pytest.approx(0.6, abs=0.01)
        # the drift does not accumulate: what is left is the bias of the one step taken from
        # the reference (its direct neighbours are not re-estimated), not twice that
        assert abs(np.median(refined[j][inner]) - truth) < 0.3 + 0.05


def test_sample_offsets_geometry():
    zero = np.zeros((8, 8, 2), np.float32)
    d = sample_offsets(zero, 2)
    # high-res pixel 0 and 1 of a low-res pixel centred at 0.5: both 0.5 px away per axis
    np.testing.assert_allclose(d, np.hypot(0.5, 0.5))
    assert np.allclose(sample_offsets(zero, 1), 0)


# -- compiled registration on a (coarser) flow grid ---------------------------------------------
def test_trace_to_reference_follows_the_chain_of_flows():
    import cv2

    from upsr.method.registration import flows_to_reference, trace_to_reference

    h, w, r = 6, 8, 2
    n, ref = 5, 2
    rng = np.random.default_rng(5)
    # smooth (affine) flows: tracing points and composing fields agree exactly up to float error
    ys, xs = np.mgrid[0 : h * r, 0 : w * r].astype(np.float32)

    def affine(a, b):
        return np.stack([a * xs + 0.3, b * ys - 0.2], axis=-1).astype(np.float32)

    fwd = [affine(*rng.uniform(-0.02, 0.02, 2)) for _ in range(n)]
    bwd = [affine(*rng.uniform(-0.02, 0.02, 2)) for _ in range(n)]
    pos = trace_to_reference(ref, fwd, bwd, (h, w), r)
    maps = flows_to_reference(ref, bwd, fwd, (h * r, w * r))
    cy = np.arange(h) * r + 0.5 * r - 0.5
    cx = np.arange(w) * r + 0.5 * r - 0.5
    assert pos.shape == (n, h, w, 2)
    np.testing.assert_allclose(pos[ref, ..., 0], np.broadcast_to(cx, (h, w)), atol=1e-5)
    gx, gy = (g.astype(np.float32) for g in np.meshgrid(cx, cy))
    for k in range(n):
        # centres sit between pixels for even r: compare with the composed field read there
        mx, my = cv2.split(cv2.remap(maps[k], gx, gy, cv2.INTER_LINEAR))
        np.testing.assert_allclose(pos[k, ..., 0], cx[None, :] + mx, atol=2e-3)
        np.testing.assert_allclose(pos[k, ..., 1], cy[:, None] + my, atol=2e-3)


def test_cumulative_flows_are_the_chain_of_compositions():
    # every map is the composition of the consecutive flows from the reference (the
    # reference's neighbours take their flow as it is: composing with the zero motion)
    xs, ys = identity_grid(H, W)
    n, ref = 5, 2
    forward = [(_field("swirl", xs + 3 * k, ys) * 0.7).astype(np.float32) for k in range(n)]
    backward = [(-_field("wave", xs, ys + 2 * k) * 0.6).astype(np.float32) for k in range(n)]
    maps = cumulative_flows(ref, backward, forward, (H, W))
    zero = np.zeros((H, W, 2), np.float32)
    expected = {ref: zero}
    for j in range(ref + 1, n):
        expected[j] = compose_flows(expected[j - 1], forward[j - 1])
    for j in range(ref - 1, -1, -1):
        expected[j] = compose_flows(expected[j + 1], backward[j + 1])
    for j in range(n):
        np.testing.assert_array_equal(maps[j], expected[j])


def test_flow_positions_read_the_flow_bilinearly_and_scale_it_to_the_output_grid():
    from upsr.method.registration import flow_positions

    flow = np.zeros((6, 8, 2), np.float32)
    qx, qy = flow_positions(flow, (12, 16))
    yy, xx = np.mgrid[0:12, 0:16]
    np.testing.assert_array_equal(qx, xx)
    np.testing.assert_array_equal(qy, yy)
    flow[..., 0], flow[..., 1] = 1.0, -0.5  # flow-grid px; the output grid is 2x finer
    qx, qy = flow_positions(flow, (12, 16))
    np.testing.assert_allclose(qx, xx + 2.0)
    np.testing.assert_allclose(qy, yy - 1.0)
    flow[..., 0] = np.arange(8, dtype=np.float32)  # a ramp: read between the samples
    qx, _ = flow_positions(flow, (12, 16))
    # output column 5's centre is at flow-grid x = (5 + 0.5)/2 - 0.5 = 2.25
    np.testing.assert_allclose(qx[:, 5], 5 + 2.0 * 2.25)
