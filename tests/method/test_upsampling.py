import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from upsr import InputError
from upsr.method.upsampling import decimate, downsample_mean, upsample_nearest


@settings(max_examples=60, deadline=None)
@given(
    r=st.integers(1, 5),
    h=st.integers(1, 6),
    w=st.integers(1, 6),
    seed=st.integers(0, 2**31 - 1),
)
def test_decimate_is_adjoint_of_upsampling(r, h, w, seed):
    rng = np.random.default_rng(seed)
    y = rng.normal(size=(h, w))
    x = rng.normal(size=(h * r, w * r))
    assert np.dot(upsample_nearest(y, r).ravel(), x.ravel()) == pytest.approx(
        np.dot(y.ravel(), decimate(x, r).ravel()), rel=1e-10, abs=1e-10
    )


@given(arrays(np.float32, (3, 4), elements=st.floats(0, 5000, width=32)), st.integers(1, 4))
def test_downsample_mean_inverts_upsampling(y, r):
    np.testing.assert_allclose(downsample_mean(upsample_nearest(y, r), r), y, rtol=1e-6)


def test_upsampling_replicates_blocks_and_keeps_invalid():
    y = np.array([[1000, 0], [2000, 3000]], np.uint16)
    up = upsample_nearest(y, 3)
    assert up.shape == (6, 6) and up.dtype == np.uint16
    assert (up[:3, :3] == 1000).all() and (up[:3, 3:] == 0).all() and (up[3:, 3:] == 3000).all()
    # a video: the last two axes are upsampled
    assert upsample_nearest(np.ones((5, 2, 3)), 2).shape == (5, 4, 6)


@pytest.mark.parametrize("r", [0, -1, 1.5, True, "2", 17, 10000])
def test_bad_scale_rejected(r):
    """Also beyond MAX_SCALE (16): r = 10000 took 24 GB of a 4×4 frame in a baseline."""
    from upsr.research import baselines

    for upsample in (upsample_nearest, baselines.nearest, baselines.bicubic_noflying):
        with pytest.raises(InputError, match=r"scale r must be an integer in 1\.\.16"):
            upsample(np.ones((2, 2)), r)


def test_decimate_needs_divisible_shape():
    with pytest.raises(InputError):
        decimate(np.ones((5, 4)), 2)


def test_resample_nearest_reads_the_nearest_pixel_at_any_ratio():
    """The state on a 256×224 output grid read on a 192×168 flow grid (r = 4, s = 3): each
    flow pixel takes the output pixel under its centre, never a blend (an edge stays an edge,
    0 stays 0)."""
    from upsr.method.upsampling import resample_nearest

    big = np.zeros((224, 256), np.float32)
    big[:, 100:] = 3000.0
    big[:, 60:100] = 1000.0
    small = resample_nearest(big, (168, 192))
    assert small.shape == (168, 192) and small.dtype == np.float32
    assert set(np.unique(small)) == {0.0, 1000.0, 3000.0}
    xs = ((np.arange(192) + 0.5) * 256 / 192).astype(int)
    np.testing.assert_array_equal(small[0], big[0, xs])
    np.testing.assert_array_equal(resample_nearest(big, big.shape), big)
