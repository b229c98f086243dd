import numpy as np
import pytest

from upsr import InputError
from upsr.method.motion import (
    available_flow_backends,
    bilateral_prefilter,
    bilateral_prefilter_nearest,
    depth_range,
    depth_to_u8,
    make_flow_backend,
    register_flow_backend,
)
from upsr.method.upsampling import upsample_nearest


def _blob(shift_x=0.0, shift_y=0.0, shape=(96, 128)):
    ys, xs = np.mgrid[0 : shape[0], 0 : shape[1]].astype(np.float32)
    d = 2500.0 + 3.0 * xs
    inside = ((xs - 60 - shift_x) / 20) ** 2 + ((ys - 45 - shift_y) / 15) ** 2 < 1
    d[inside] = 1200.0
    return d.astype(np.float32)


def test_prefilter_smooths_noise_keeps_edges_and_invalid():
    rng = np.random.default_rng(0)
    clean = _blob()
    noisy = clean + rng.laplace(0, 20, clean.shape).astype(np.float32)
    noisy[:5, :5] = 0
    out = bilateral_prefilter(noisy, 40.0, 2.0)
    assert (out[:5, :5] == 0).all()
    flat = (slice(10, 20), slice(100, 120))
    assert np.std(out[flat] - clean[flat]) < 0.6 * np.std(noisy[flat] - clean[flat])
    # the blob edge stays sharp: no value between the two surfaces far from either
    assert not ((out > 1500) & (out < 2200)).any()


def test_fixed_mapping():
    near, far = depth_range(np.array([[0, 1000, 2000, 3000]], np.float32))
    assert 0 <= near < 1000 and far > 3000
    img = depth_to_u8(np.array([[0, near, far]], np.float32), near, far)
    assert img.tolist() == [[0, 255, 1]]
    assert depth_range(np.zeros((2, 2))) == (0.0, 10000.0)


def test_the_mapping_rounds_as_its_float64_expression():
    """255 − (clip(d, near, far) − near) · 254 / (far − near) in float64, half to even; 0 for
    no depth and NaN; any shape and memory order."""
    rng = np.random.default_rng(0)
    near, far = 1234.5, 4321.0
    d = rng.uniform(-100.0, 5000.0, (3, 37, 41)).astype(np.float32)
    d[0, 0, :10] = (near + (np.arange(10) + 0.5) * (far - near) / 254.0).astype(np.float32)
    d[1, 2, 3] = np.nan
    x = np.clip(d.astype(np.float64), near, far)
    want = np.where(d > 0, np.rint(255.0 - (x - near) * 254.0 / (far - near)), 0.0)
    np.testing.assert_array_equal(depth_to_u8(d, near, far), want.astype(np.uint8))
    np.testing.assert_array_equal(depth_to_u8(d[:, ::2, 1::3], near, far), want[:, ::2, 1::3])
    assert depth_to_u8(d, np.float32(near), far).dtype == np.uint8


@pytest.mark.parametrize("name", ["dis", "farneback"])
def test_flow_static_is_zero_and_shift_is_found(name):
    flow = make_flow_backend(name, "medium")
    r = 4
    a = upsample_nearest(_blob(), 1)
    rng_ = depth_range(a)
    g0 = depth_to_u8(bilateral_prefilter(a, 40, 3.5), *rng_)
    assert np.abs(flow(g0, g0)).max() < 0.1
    b = _blob(shift_x=r * 0.75, shift_y=-r * 0.5)
    g1 = depth_to_u8(bilateral_prefilter(b, 40, 3.5), *rng_)
    f = flow(g0, g1)
    inside = _blob() < 1500
    core = inside & (np.abs(np.gradient(_blob())[1]) < 1)
    med = np.median(f[core], axis=0)
    np.testing.assert_allclose(med, [3.0, -2.0], atol=0.5)


def test_backend_registry():
    assert {"dis", "farneback"} <= set(available_flow_backends())
    with pytest.raises(InputError, match="unknown flow backend"):
        make_flow_backend("nope")
    register_flow_backend(
        "zero", lambda preset="medium": lambda a, b: np.zeros((*a.shape, 2), np.float32)
    )
    assert make_flow_backend("zero")(np.zeros((3, 4), np.uint8), None).shape == (3, 4, 2)


def test_spurious_motion_is_suppressed_but_real_motion_and_invalid_pixels_are_kept():
    from upsr.method.motion import suppress_spurious_motion

    rng = np.random.default_rng(0)
    a = _blob() + rng.normal(0, 3, (96, 128)).astype(np.float32)
    a[:, :8] = 0  # no depth there
    flow = rng.normal(0, 1.5, (96, 128, 2)).astype(np.float32)  # noise-like "motion"
    out = suppress_spurious_motion(a, a.copy(), flow, window_px=9, noise_mm=3.0, edge_mm=100.0)
    flat = (slice(5, 90), slice(100, 120))
    assert np.abs(out[flat]).max() == 0  # static surface: no motion
    np.testing.assert_array_equal(out[:, :8], flow[:, :8])  # no evidence: untouched
    # a real shift of the blob is kept on the blob
    b = _blob(shift_x=4.0) + rng.normal(0, 3, (96, 128)).astype(np.float32)
    real = np.zeros_like(flow)
    real[..., 0] = 4.0
    kept = suppress_spurious_motion(a, b, real, window_px=9, noise_mm=3.0, edge_mm=100.0)
    assert (kept[40:50, 78:82, 0] == 4.0).all()  # at the blob's moving edge


def test_the_flow_of_holes_is_judged_by_their_pattern_when_asked():
    """A hole of both frames on a static noisy plane: a flow pointing from it onto the plane
    (which would carry the plane into it) is zeroed with ``holes``, left alone without; the
    hole a moving blob leaves keeps its flow, as do pixels without depth far from any."""
    from upsr.method.motion import suppress_spurious_motion

    rng = np.random.default_rng(2)
    a = np.full((64, 64), 2000.0, np.float32) + rng.normal(0, 3, (64, 64)).astype(np.float32)
    a[30:34, 30:34] = 0.0  # a hole of every frame
    a[:, :6] = 0.0  # nothing there, ever
    flow = np.zeros((64, 64, 2), np.float32)
    flow[26:38, 26:38, 0] = 2.5  # from the hole onto the plane
    kw = {"window_px": 5, "noise_mm": 3.0, "edge_mm": 100.0, "edge_window_px": 9}
    left = suppress_spurious_motion(a, a.copy(), flow, **kw)
    judged = suppress_spurious_motion(a, a.copy(), flow, holes=True, **kw)
    assert (left[30:34, 30:34, 0] == 2.5).all() and not judged[30:34, 30:34].any()
    np.testing.assert_array_equal(judged[:, :6], flow[:, :6])  # no evidence either way
    # a blob moved 4 px right: the pixels it left (no depth now, depth before) keep the flow
    # that finds it where it was
    prev = np.zeros((64, 64), np.float32)
    prev[20:40, 20:40] = 1500.0
    now = np.zeros((64, 64), np.float32)
    now[20:40, 24:44] = 1500.0
    back = np.zeros((64, 64, 2), np.float32)
    back[..., 0] = -4.0  # now -> prev
    kept = suppress_spurious_motion(now, prev, back, holes=True, **kw)
    np.testing.assert_array_equal(kept[20:40, 20:24], back[20:40, 20:24])


def test_spurious_motion_on_8bit_images_equals_their_float_values():
    from upsr.method.motion import suppress_spurious_motion

    rng = np.random.default_rng(4)
    a = depth_to_u8(_blob() + rng.normal(0, 6, (96, 128)).astype(np.float32), 2000.0, 3200.0)
    b = depth_to_u8(
        _blob(shift_x=3.0) + rng.normal(0, 6, (96, 128)).astype(np.float32), 2000.0, 3200.0
    )
    a[:, :8] = 0
    flow = rng.normal(0, 2.0, (96, 128, 2)).astype(np.float32)
    flow[30:60, 40:80, 0] += 3.0
    kw = {"window_px": 7, "noise_mm": 2.0, "edge_mm": 12.0, "edge_window_px": 13}
    as_u8 = suppress_spurious_motion(a, b, flow, **kw)
    as_float = suppress_spurious_motion(a.astype(np.float32), b.astype(np.float32), flow, **kw)
    assert (as_u8 == 0).any() and (as_u8 != 0).any()  # both outcomes occur
    np.testing.assert_array_equal(as_u8, as_float)


@pytest.mark.parametrize("name", ["dis", "farneback"])
def test_flow_does_not_depend_on_earlier_calls(name):
    # a chunk of a video must give what the whole run gives: no state between calls
    rng = np.random.default_rng(1)
    a = (rng.uniform(0, 255, (40, 48))).astype(np.uint8)
    b = np.roll(a, 2, axis=1)
    fresh = make_flow_backend(name)(a, b)
    used = make_flow_backend(name)
    used(b, a)
    np.testing.assert_array_equal(used(a, b), fresh)


@pytest.mark.parametrize("preset", ["ultrafast", "fast", "medium"])
def test_dis_backend_result_does_not_depend_on_earlier_pairs(preset):
    # the backend keeps its OpenCV object between pairs: pairs of other sizes (small ones,
    # on which OpenCV lowers the finest pyramid level, and a tiny padded one) and other
    # contents computed before must not change a result
    import cv2

    rng = np.random.default_rng(2)
    used = make_flow_backend("dis", preset)
    for shape in ((40, 48), (12, 9), (32, 40), (64, 80), (168, 192), (64, 80), (40, 48)):
        for _ in range(3):
            a = rng.uniform(0, 255, shape).astype(np.uint8)
            if rng.random() < 0.5:
                a = cv2.GaussianBlur(a, (5, 5), 1.5)
            b = np.roll(a, int(rng.integers(-4, 5)), axis=int(rng.integers(0, 2)))
            np.testing.assert_array_equal(used(a, b), make_flow_backend("dis", preset)(a, b))
            np.testing.assert_array_equal(used(b, a), make_flow_backend("dis", preset)(b, a))


@pytest.mark.parametrize(
    ("factor", "sigma_px", "shape"),
    [(3, 2.625, (23, 29)), (2, 1.75, (20, 31)), (4, 3.5, (15, 14)), (3, 1.0, (9, 11))],
)
def test_block_prefilter_equals_opencv_on_the_upsampled_frame(factor, sigma_px, shape):
    rng = np.random.default_rng(3)
    low = rng.uniform(1500, 1600, shape).astype(np.float32)
    low[shape[0] // 3 :, : shape[1] // 2] -= 700  # a depth edge
    low[rng.random(shape) < 0.1] = 0.0  # holes
    expected = bilateral_prefilter(upsample_nearest(low, factor), 40.0, sigma_px)
    out = bilateral_prefilter_nearest(low, factor, 40.0, sigma_px)
    assert out.shape == expected.shape and out.dtype == np.float32
    np.testing.assert_allclose(out, expected, atol=0.01)
    assert (out[upsample_nearest(low, factor) == 0] == 0).all()


def test_block_prefilter_small_constant_and_factor_one_frames():
    # factor 1 and frames smaller than the window go to OpenCV: its result exactly
    rng = np.random.default_rng(4)
    for low, factor in (
        (rng.uniform(1000, 2000, (10, 12)).astype(np.float32), 1),
        (rng.uniform(1000, 2000, (2, 3)).astype(np.float32), 3),
    ):
        expected = bilateral_prefilter(upsample_nearest(low, factor), 40.0, 2.625)
        np.testing.assert_array_equal(
            bilateral_prefilter_nearest(low, factor, 40.0, 2.625), expected
        )
    # a constant frame stays exactly constant (OpenCV: within float rounding)
    low = np.full((12, 12), 1234.0, np.float32)
    out = bilateral_prefilter_nearest(low, 3, 40.0, 2.625)
    assert (out == 1234.0).all() and out.shape == (36, 36)
    np.testing.assert_allclose(
        out, bilateral_prefilter(upsample_nearest(low, 3), 40.0, 2.625), atol=0.01
    )


def test_block_prefilter_treats_nan_inf_and_negative_as_invalid():
    rng = np.random.default_rng(5)
    low = rng.uniform(1500, 1600, (20, 24)).astype(np.float32)
    bad = low.copy()
    bad[3, 4], bad[10, 10], bad[15, 2], bad[0, 0] = np.nan, np.inf, -50.0, 0.0
    clean = bad.copy()
    clean[~(np.isfinite(clean) & (clean > 0))] = 0.0
    out = bilateral_prefilter_nearest(bad, 3, 40.0, 2.625)
    assert np.isfinite(out).all()
    np.testing.assert_array_equal(out, bilateral_prefilter_nearest(clean, 3, 40.0, 2.625))
    assert (out[upsample_nearest(clean, 3) == 0] == 0).all()
