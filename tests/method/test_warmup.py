"""upsr.method.warmup: synthetic frames through throw-away engines before a stream starts."""

import numpy as np
import pytest

from upsr.errors import InputError
from upsr.method import recursive, windowed
from upsr.method.config import UPSRConfig
from upsr.method.warmup import WARM_UP_FRAMES, warm_up, warm_up_frames


def test_warm_up_frames():
    a = warm_up_frames((30, 40), 4)
    assert a.shape == (4, 30, 40) and a.dtype == np.float32
    np.testing.assert_array_equal(a, warm_up_frames((30, 40), 4))  # (a fixed seed)
    assert 0.002 < (a == 0).mean() < 0.03  # some pixels without depth
    valid = a[a > 0]
    assert valid.min() > 900 and valid.max() < 2800  # the box 1 m, the wall 2-2.7 m
    with pytest.raises(InputError):
        warm_up_frames((1, 40))


@pytest.mark.parametrize("remove_mixed", ["auto", True, False])
def test_warm_up_runs_each_mixed_pixel_path_through_its_own_engine(monkeypatch, remove_mixed):
    pushed = []
    push = recursive.RecursiveUPSR.push

    def recorded(self, frame):
        pushed.append((id(self), self.config.remove_mixed, np.shape(frame)))
        return push(self, frame)

    monkeypatch.setattr(recursive.RecursiveUPSR, "push", recorded)
    warm_up(UPSRConfig(scale=2, n_frames=9, mode="recursive", remove_mixed=remove_mixed), (24, 32))
    paths = [False, True] if remove_mixed == "auto" else [remove_mixed]
    assert [p[1:] for p in pushed] == [(m, (24, 32)) for m in paths for _ in range(WARM_UP_FRAMES)]
    assert len({p[0] for p in pushed}) == len(paths)  # a new engine per path


def test_warm_up_of_the_windowed_mode(monkeypatch):
    windows = []
    process = windowed.UPSR.process

    def recorded(self, frames):
        windows.append((self.config.n_frames, self.config.remove_mixed, np.shape(frames)))
        return process(self, frames)

    monkeypatch.setattr(windowed.UPSR, "process", recorded)
    # (a valid range that keeps none of the synthetic frames' depths changes nothing)
    warm_up(UPSRConfig(scale=2, n_frames=9, valid_range_mm=(5000, 8000)), (24, 32))
    assert windows == [(3, False, (3, 24, 32)), (3, True, (3, 24, 32))]


def test_warm_up_leaves_an_engines_output_unchanged():
    frames = warm_up_frames((20, 24), 4) + 500.0
    cfg = UPSRConfig(scale=2, n_frames=3, mode="recursive")
    fresh = recursive.RecursiveUPSR(config=cfg, workers=0)
    before = [fresh.push(f) for f in frames]
    engine = recursive.RecursiveUPSR(config=cfg, workers=0)
    engine.push(frames[0])
    warm_up(cfg, (16, 28))  # (another shape, while an engine is running)
    after = [before[0], *(engine.push(f) for f in frames[1:])]
    np.testing.assert_array_equal(np.stack(after), np.stack(before))
