import numpy as np
import pytest
from scipy import ndimage as ndi

import upsr
from upsr import InputError
from upsr.method.upsampling import upsample_nearest
from upsr.research.baselines import nearest
from upsr.research.metrics import evaluate
from upsr.research.synth import dynamic_scene


def _static_video(t=7, seed=0, sigma=20.0):
    rng = np.random.default_rng(seed)
    _ys, xs = np.mgrid[0:24, 0:32].astype(np.float32)
    clean = 2000 + 4 * xs
    clean[8:16, 10:20] = 1200
    noise = rng.laplace(0, sigma / np.sqrt(2), (t, 24, 32)).astype(np.float32)
    return (clean + noise).astype(np.float32)


def test_static_scene_motion_is_zero_and_output_is_median_of_frames():
    # noise of 10 mm: no Laplace outlier comes near the 100 mm edge threshold, which would
    # (rightly) make the flow around it count as an edge's
    video = _static_video(sigma=10.0)
    # the paper's fusion (every sample votes); the trust test of the samples is checked below
    engine = upsr.UPSR(scale=2, n_frames=7, deblur=False, edge_weight_px=None, trust_k=None)
    outs = [engine.push(f) for f in video]
    flows = np.stack([*engine._fwd.values(), *engine._bwd.values()])
    magnitude = np.hypot(flows[..., 0], flows[..., 1])
    assert np.median(magnitude) == 0.0
    assert np.percentile(magnitude, 95) < 1.0
    out = outs[-1]  # frame 0, window = all 7 frames
    expected = np.median(upsample_nearest(video, 2), axis=0)
    same = np.isclose(out, expected, atol=1e-3)
    box = np.zeros(same.shape, bool)
    box[16:32, 20:40] = True
    # flows are kept within 2r px of a depth edge (they place the edge), zeroed elsewhere
    edges = ndi.binary_dilation(box, iterations=5) & ~ndi.binary_erosion(box, iterations=5)
    assert same[~edges].mean() > 0.93
    assert same.mean() > 0.9
    # with the trust test (default), a few Laplace outliers beyond 3σ of the reference's
    # robust depth no longer vote: the median of the others, within the noise of it
    trusted = upsr.super_resolve(video, 2, 7, deblur=False, edge_weight_px=None)[0]
    close = np.abs(trusted - expected) < 10.0
    assert close[~edges].mean() > 0.98


def test_streaming_equals_batch_and_latency():
    scene = dynamic_scene(n_frames=8, lowres_shape=(16, 20), scale=2, noise_sigma_mm=20, seed=1)
    batch = upsr.super_resolve(scene.lowres, 2, 5)
    engine = upsr.UPSR(scale=2, n_frames=5)
    got = []
    for k, frame in enumerate(scene.lowres):
        out = engine.push(frame)
        assert (out is None) == (k < 4)
        if out is not None:
            got.append(out)
    got += engine.flush()
    assert len(got) == 8
    np.testing.assert_array_equal(np.stack(got), batch)
    # flush resets: the same engine processes a second video identically
    np.testing.assert_array_equal(np.stack(list(engine.process(scene.lowres))), batch)
    engine.push(scene.lowres[0])
    engine.reset()
    assert engine.frames_seen == 0


def test_output_contract():
    scene = dynamic_scene(n_frames=5, lowres_shape=(12, 14), scale=3, noise_sigma_mm=10, seed=2)
    frames_u16 = np.round(scene.lowres).astype(np.uint16)
    out = upsr.super_resolve(frames_u16, 3, 3)
    assert out.shape == (5, 36, 42) and out.dtype == np.float32
    assert np.isfinite(out).all() and (out >= 0).all()


@pytest.mark.slow
@pytest.mark.parametrize("background", ["wall", "none"])
def test_end_to_end_dynamic_scene(background):
    sigma = 30.0
    scene = dynamic_scene(
        n_frames=11,
        lowres_shape=(32, 40),
        scale=4,
        noise_sigma_mm=sigma,
        background=background,
        seed=3,
    )
    out = upsr.super_resolve(scene.lowres, 4, 9)
    sl = slice(3, 8)
    m = evaluate(out[sl], scene.truth[sl], 4)
    m_near = evaluate(nearest(scene.lowres, 4)[sl], scene.truth[sl], 4)
    assert m["surface_rmse"] < 0.4 * sigma  # far below the noise
    assert m["flying_pixels"] < 0.005
    assert m["edge_accuracy"] >= m_near["edge_accuracy"]
    # where the reference measured depth the output keeps it (as nearest does: a thin fast
    # part never vanishes), where it did not the window's majority fills it (a dropout):
    # at a silhouette over nothing that may add a few pixels nearest does not have
    assert m["invented"] <= m_near["invented"] + 1e-3
    assert m["rmse"] < m_near["rmse"]
    if background == "none":
        # where the truth is 0 and every frame of the window says "no return", output 0
        up = upsample_nearest(scene.lowres, 4)
        for t in range(3, 8):
            s = min(max(t - 4, 0), 11 - 9)
            all_invalid = (up[s : s + 9] == 0).all(axis=0) & (scene.truth[t] == 0)
            assert all_invalid.any()
            assert (out[t][all_invalid] == 0).all()


def test_empty_frame_inside_video_is_filled():
    video = _static_video(t=5)
    video[2] = 0
    out = upsr.super_resolve(video, 2, 5)
    assert (out[2] > 0).mean() > 0.95


@pytest.mark.parametrize(
    ("frames", "kwargs", "match"),
    [
        (np.ones((3, 4, 4)), {"n_frames": 5}, "only 3 frame"),
        (np.ones((3, 4, 4)), {"n_frames": 0}, "n_frames"),
        (np.ones((3, 4, 4)), {"scale": 0}, "scale"),
        (np.zeros((3, 4, 4)), {}, "no valid depth"),
        (np.full((3, 4, 4), -1.0), {}, "negative"),
        (np.ones((4, 4)), {}, "shape"),
    ],
)
def test_bad_input(frames, kwargs, match):
    args = {"scale": 2, "n_frames": 3, **kwargs}
    with pytest.raises(InputError, match=match):
        upsr.super_resolve(frames, **args)


def test_streaming_bad_input():
    engine = upsr.UPSR(scale=2, n_frames=3)
    engine.push(np.ones((4, 4)))
    with pytest.raises(InputError, match="differs"):
        engine.push(np.ones((5, 4)))
    with pytest.raises(InputError, match="only 1 frame"):
        engine.flush()
    engine = upsr.UPSR(scale=2, n_frames=2)
    for _ in range(3):
        engine.push(np.zeros((4, 4)))
    with pytest.raises(InputError, match="no valid depth"):
        engine.flush()


def test_chunk_with_the_videos_statistics_equals_the_whole_run():
    from upsr.method.statistics import pinned_config
    from upsr.method.windowed import window_start

    scene = dynamic_scene(n_frames=14, lowres_shape=(16, 20), scale=2, noise_sigma_mm=20, seed=4)
    n = 5
    whole = upsr.super_resolve(scene.lowres, 2, n)
    # what "auto" picks from the video's first window: depth range, noise, estimator, trust
    cfg = pinned_config(scene.lowres[:n], upsr.UPSRConfig(scale=2, n_frames=n))
    assert cfg.fusion_estimator in ("mean", "median") and cfg.trust_noise_mm is not None
    a, b = 7, 14  # output frames of the chunk; its windows need input frames [lo, b)
    lo = window_start(a, 14, cfg)
    part = upsr.super_resolve(scene.lowres[lo:b], 2, config=cfg)
    np.testing.assert_array_equal(part[a - lo :], whole[a:b])


def test_a_room_seen_by_a_moving_camera_reaches_frames_by_its_noise_not_its_motion():
    """The camera's motion over the room's slanted surfaces makes the temporal differences
    read three times the noise: taken for a sample's noise, it would let every pixel of a
    steep slope draw on all N frames (with their registration error times the slope) and
    leave the radial offsets of the misregistered frames unmeasured. The noise read in
    space (``reach_noise_mm``) lowers the surfaces' error by a fifth."""
    import dataclasses

    from upsr.method.statistics import pinned_config
    from upsr.research.synth.realistic import degrade, make_realistic

    video = make_realistic("room", (56, 64), scale=4, n_frames=9, seed=0)
    low = degrade(video, "laplace", np.random.default_rng(0), sigma_mm=10.0)
    cfg = pinned_config(low, upsr.UPSRConfig(scale=4, n_frames=9))
    assert cfg.reach_noise_mm < cfg.trust_noise_mm / 2
    errors = []
    for reach in (cfg.reach_noise_mm, cfg.trust_noise_mm):
        out = upsr.super_resolve(low, 4, config=dataclasses.replace(cfg, reach_noise_mm=reach))
        errors.append(evaluate(out, video.truth, 4)["surface_rmse"])
    assert errors[0] < 0.85 * errors[1]


def test_the_finishing_judges_slopes_by_a_samples_noise(monkeypatch):
    """The slopes' significance (``slopes.follow_slopes``, in the finishing) takes the
    sample's noise, not the trust's σ that a camera moving over slopes inflates."""
    from upsr.method import windowed

    seen = []
    finish = windowed.finish_frame

    def spy(*args, **kwargs):
        seen.append(kwargs["noise_mm"])
        return finish(*args, **kwargs)

    monkeypatch.setattr(windowed, "finish_frame", spy)
    rng = np.random.default_rng(4)
    t, y, x = np.meshgrid(np.arange(5), np.arange(24), np.arange(32), indexing="ij")
    clean = np.where(x < 16, 1500.0 + 8.0 * (y + 6 * t), 2500.0 + 8.0 * (x - 6 * t))
    frames = (clean + rng.laplace(0, 10 / np.sqrt(2), clean.shape)).astype(np.float32)
    engine = upsr.UPSR(scale=2, n_frames=5, workers=0)
    for f in frames:
        engine.push(f)
    stats = engine.statistics
    assert stats.reach_noise_mm < stats.trust_noise_mm / 2
    assert seen and all(v == stats.reach_noise_mm for v in seen)


def test_stage_timings_are_recorded_and_kept_across_videos():
    scene = dynamic_scene(n_frames=6, lowres_shape=(12, 16), scale=2, noise_sigma_mm=10, seed=2)
    engine = upsr.UPSR(scale=2, n_frames=3)
    list(engine.process(scene.lowres))
    first = dict(engine.timings)
    assert set(first) == set(upsr.method.windowed.STAGES)
    assert all(v > 0 for v in first.values())
    list(engine.process(scene.lowres))
    assert all(engine.timings[k] > first[k] for k in first)


def test_flow_grid_scale_is_used_and_a_full_grid_matches_the_paper_setting():
    scene = dynamic_scene(n_frames=6, lowres_shape=(16, 20), scale=4, noise_sigma_mm=10, seed=3)
    coarse = upsr.UPSR(scale=4, n_frames=3, flow_scale=2)
    full = upsr.UPSR(scale=4, n_frames=3)  # 20 px wide: s = r (a grid of 80 < 192 px)
    coarse.push(scene.lowres[0])
    full.push(scene.lowres[0])
    assert coarse._s == 2 and full._s == 4
    assert coarse._pre[0].shape == (32, 40) and full._pre[0].shape == (64, 80)
    coarse.reset()
    full.reset()
    a = np.stack(list(coarse.process(scene.lowres)))
    b = np.stack(list(full.process(scene.lowres)))
    assert a.shape == b.shape == scene.truth.shape
    # both are valid super-resolutions of the same scene, not the same numbers
    assert not np.array_equal(a, b)
    for out in (a, b):
        m = evaluate(out, scene.truth, 4)
        assert m["flying_pixels"] == 0.0
        assert m["surface_rmse"] < 10.0


def test_engine_state_stays_bounded_on_long_videos():
    # a long video keeps about N frames of state, whatever its length
    scene = dynamic_scene(n_frames=40, lowres_shape=(12, 16), scale=2, noise_sigma_mm=10, seed=5)
    engine = upsr.UPSR(scale=2, n_frames=5)
    sizes = []
    for frame in scene.lowres:
        engine.push(frame)
        sizes.append(max(len(d) for d in (engine._lowres, engine._pre, engine._guide, engine._fwd)))
    assert max(sizes) <= 5 + 1
    assert len(engine.flush()) == 4


def test_feed_has_half_the_latency_and_the_same_frames():
    scene = dynamic_scene(n_frames=9, lowres_shape=(12, 16), scale=2, noise_sigma_mm=10, seed=6)
    batch = upsr.super_resolve(scene.lowres, 2, 5)
    engine = upsr.UPSR(scale=2, n_frames=5)
    counts = [len(out) for out in (engine.feed(f) for f in scene.lowres[:4])]
    assert counts == [0, 0, 0, 0]
    engine.reset()
    got = []
    returned_at = {}
    for k, frame in enumerate(scene.lowres):
        for out in engine.feed(frame):
            returned_at[len(got)] = k
            got.append(out)
    # N = 5: frames 0-2 once the first window is full, then frame t after frame t + 2
    assert returned_at == {0: 4, 1: 4, 2: 4, 3: 5, 4: 6, 5: 7, 6: 8}
    got.extend(engine.flush())
    np.testing.assert_array_equal(np.stack(got), batch)


@pytest.mark.parametrize("workers", [1, 2, 3])
def test_windows_finished_in_the_background_give_the_same_frames(workers):
    scene = dynamic_scene(n_frames=13, lowres_shape=(14, 18), scale=2, noise_sigma_mm=20, seed=7)
    serial = upsr.super_resolve(scene.lowres, 2, 5, workers=0)
    engine = upsr.UPSR(scale=2, n_frames=5, workers=workers)
    assert engine.workers == workers
    pushed = [engine.push(f) for f in scene.lowres]
    assert [o is None for o in pushed] == [True] * 4 + [False] * 9  # the same latency
    got = [o for o in pushed if o is not None] + engine.flush()
    np.testing.assert_array_equal(np.stack(got), serial)
    fed = [o for f in scene.lowres for o in engine.feed(f)] + engine.flush()
    np.testing.assert_array_equal(np.stack(fed), serial)
    np.testing.assert_array_equal(np.stack(list(engine.process(scene.lowres))), serial)
    np.testing.assert_array_equal(upsr.super_resolve(scene.lowres, 2, 5, workers=workers), serial)
    # a reset with windows still being finished forgets them; the next video is unaffected
    for frame in scene.lowres[:9]:
        engine.push(frame)
    engine.reset()
    np.testing.assert_array_equal(np.stack(list(engine.process(scene.lowres))), serial)


def test_workers_parameter():
    assert upsr.UPSR(2, 3, workers=0).workers == 0
    for bad in (-1, 1.5, True, "2"):
        with pytest.raises(InputError, match="workers"):
            upsr.UPSR(2, 3, workers=bad)
    # a custom flow backend may keep state: windows are finished one at a time
    dis = upsr.method.motion.make_flow_backend("dis")
    assert upsr.UPSR(2, 3, flow_backend=dis, workers=2).workers == 0


def test_an_error_while_finishing_a_window_reaches_the_caller(monkeypatch):
    import upsr.method.windowed as pipeline

    scene = dynamic_scene(n_frames=8, lowres_shape=(12, 16), scale=2, noise_sigma_mm=10, seed=8)
    calls = []

    def broken(fused, cfg, **_):
        calls.append(1)
        if len(calls) == 2:
            raise RuntimeError("deblurring failed")
        return fused

    monkeypatch.setattr(pipeline, "finish_fused", broken)
    engine = upsr.UPSR(scale=2, n_frames=3, workers=2)
    with pytest.raises(RuntimeError, match="deblurring failed"):
        for frame in scene.lowres:
            engine.push(frame)
    engine.reset()
    monkeypatch.setattr(pipeline, "finish_fused", lambda fused, cfg, **_: fused)
    assert len(list(engine.process(scene.lowres))) == 8


def test_sample_chains_kept_across_windows_equal_the_traced_ones(monkeypatch):
    # the engine extends each frame's chain of sample positions by one flow per window;
    # the positions must be those of tracing every window from scratch
    import upsr.method.windowed as pipeline
    from upsr.method.registration import trace_to_reference
    from upsr.method.windowed import window_start

    scene = dynamic_scene(n_frames=9, lowres_shape=(12, 16), scale=2, noise_sigma_mm=10, seed=9)
    seen = []
    splat = pipeline.splat_points

    def spy(values, positions, shape, radius):
        seen.append(np.array(positions))
        return splat(values, positions, shape, radius)

    monkeypatch.setattr(pipeline, "splat_points", spy)
    engine = upsr.UPSR(scale=2, n_frames=5, workers=0)
    fwd, bwd = {}, {}
    for frame in scene.lowres:
        engine.push(frame)
        fwd.update(engine._fwd)
        bwd.update(engine._bwd)
    engine.flush()
    assert len(seen) == 9
    for t, positions in enumerate(seen):
        s = window_start(t, 9, engine.config)
        idx = range(s, s + 5)
        expected = trace_to_reference(
            t - s, [fwd.get(k) for k in idx], [bwd.get(k) for k in idx], (12, 16), 2
        )
        np.testing.assert_array_equal(positions, expected)


def test_the_videos_statistics_stay_readable_after_flush():
    """UPSR.statistics: None before the first window, the video's choices from its N-th
    frame on, and still those after flush() (which resets the engine for the next video)."""
    scene = dynamic_scene(n_frames=6, lowres_shape=(12, 16), scale=2, noise_sigma_mm=10, seed=3)
    engine = upsr.UPSR(2, 3)
    assert engine.statistics is None
    engine.push(scene.lowres[0])
    assert engine.statistics is None
    for f in scene.lowres[1:]:
        engine.push(f)
    during = engine.statistics
    assert during is not None and during.estimator in ("mean", "median")
    assert during.trust_noise_mm > 0
    engine.flush()
    assert engine.statistics == during
