"""The robust noise estimate (upsr.method.noise)."""

import numpy as np
import pytest

from upsr.method.noise import estimate_noise_mm


def test_noise_estimate():
    rng = np.random.default_rng(3)
    z = 2000 + rng.normal(0, 10, (200, 200)).astype(np.float32)
    assert estimate_noise_mm(z) == pytest.approx(10, rel=0.1)
