"""upsr.method.outliers: isolated outliers become unknown, everything else is untouched."""

import numpy as np
import pytest

import upsr
from upsr.errors import InputError
from upsr.method.outliers import remove_speckles
from upsr.research._oracle_speckles import remove_speckles_opencv


def _scene() -> np.ndarray:
    z = np.full((24, 24), 2000.0, np.float32)
    z += np.linspace(0.0, 60.0, 24, dtype=np.float32)[None]  # a slanted wall: steps < 3 mm
    z[12:18, 12:18] = 1200.0  # a real object of 36 px
    z[:, 22:] = 0.0  # no return
    return z


def test_isolated_outliers_become_unknown_and_nothing_else_changes():
    z = _scene()
    noisy = z.copy()
    noisy[4, 4] = z[4, 4] + 300.0  # one pixel, 300 mm off its wall
    noisy[8:10, 6:8] = z[8:10, 6:8] - 250.0  # a 2x2 block (one low-res pixel at r = 2)
    noisy[20, 21] = 900.0  # next to the no-return region: still an island
    out = remove_speckles(noisy, 4, 100.0)
    removed = (noisy > 0) & (out == 0)
    expected = np.zeros_like(removed)
    expected[4, 4] = expected[8:10, 6:8] = expected[20, 21] = True
    np.testing.assert_array_equal(removed, expected)
    keep = ~expected
    np.testing.assert_array_equal(out[keep], noisy[keep])  # bit for bit
    assert out.dtype == np.float32


def test_regions_larger_than_the_size_or_joined_by_small_steps_stay():
    z = _scene()
    assert np.array_equal(remove_speckles(z, 35, 100.0), z)  # the object has 36 px
    assert (remove_speckles(z, 36, 100.0)[12:18, 12:18] == 0).all()
    z2 = z.copy()
    z2[4, 4] += 90.0  # within 100 mm of its neighbours: part of the wall
    assert np.array_equal(remove_speckles(z2, 4, 100.0), z2)
    assert np.array_equal(remove_speckles(z2, 0, 100.0), z2)  # 0: keep everything


def test_an_image_of_speckles_only_is_kept():
    """Nothing for the islands to be cut off from (a 1×1 video upsampled, or two blocks in an
    empty frame): kept as they are (a 1×1 video came out all 0 from super_resolve), by the
    OpenCV oracle too."""

    one = np.full((2, 2), 1500.0, np.float32)
    two = np.zeros((8, 8), np.float32)
    two[1:3, 1:3], two[5:7, 5:7] = 1500.0, 2500.0
    for z in (one, two):
        np.testing.assert_array_equal(remove_speckles(z, 4, 100.0), z)
        np.testing.assert_array_equal(remove_speckles_opencv(z, 4, 100.0), z)
    video = np.full((5, 1, 1), 1500.0, np.float32)
    assert (upsr.super_resolve(video, 2, n_frames=3) > 0).all()


@pytest.mark.parametrize("seed", range(4))
def test_the_same_regions_as_opencvs_speckle_filter(seed):
    # random depth maps: surfaces, holes, islands of every size, near the int16 range too
    rng = np.random.default_rng(seed)
    for _ in range(250):
        h, w = rng.integers(1, 40, 2)
        levels = rng.choice([1000.0, 1060.0, 1200.0, 3000.0, 40000.0], size=3)
        z = rng.choice(levels, size=(h, w)) + rng.normal(0.0, 25.0, (h, w))
        z[rng.random((h, w)) < rng.uniform(0.0, 0.4)] = 0.0
        size, diff = int(rng.integers(0, 20)), float(rng.choice([30.0, 100.0, 400.0]))
        np.testing.assert_array_equal(
            remove_speckles(z, size, diff), remove_speckles_opencv(z, size, diff)
        )


def test_unknown_pixels_and_far_depths():
    z = _scene() * 20.0  # up to 41 m: beyond int16 millimetres
    z[3, 3] += 4000.0
    z[5, 5] = np.nan
    out = remove_speckles(z, 4, 2000.0)
    assert out[3, 3] == 0 and out[5, 5] == 0
    assert np.count_nonzero((out == 0) & (np.nan_to_num(z) > 0)) == 1  # only the outlier
    assert (remove_speckles(np.zeros((5, 5)), 4) == 0).all()


@pytest.mark.parametrize(
    "args",
    [
        (np.ones((2, 3, 3)), 4, 100.0),
        (np.ones((3, 3)), -1, 100.0),
        (np.ones((3, 3)), 1.5, 100.0),
        (np.ones((3, 3)), 4, 0.0),
        (np.ones((3, 3)), 4, np.inf),
    ],
)
def test_bad_arguments(args):
    with pytest.raises(InputError):
        remove_speckles(*args)


def test_the_pipeline_removes_a_lone_outlier_sample():
    """A static wall whose frame 2 holds one sample 400 mm off: the median of the window never
    lets it through, and what the engine outputs holds no island."""
    rng = np.random.default_rng(0)
    frames = (2500.0 + rng.laplace(0.0, 5.0, (5, 16, 16))).astype(np.float32)
    out = upsr.super_resolve(frames, 2, 5)
    assert (out > 0).all()
    for f in out:
        assert np.array_equal(remove_speckles(f, 4, 100.0), f)
