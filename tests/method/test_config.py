import numpy as np
import pytest

import upsr
from upsr import DeblurConfig, InputError, UPSRConfig


def test_defaults_are_valid_and_documented():
    cfg = UPSRConfig(scale=4)
    assert cfg.n_frames == 9 and cfg.half_before == 4
    assert cfg.deblur.enabled and cfg.deblur.radius_px >= 1
    assert UPSRConfig.__doc__ and "n_frames" in UPSRConfig.__doc__
    assert "lam" in DeblurConfig.__doc__


def test_from_options_routes_deblur_prefix():
    cfg = UPSRConfig.from_options(2, 5, deblur_lam=0.1, deblur_iterations=3, refine=False)
    assert cfg.deblur.lam == 0.1 and cfg.deblur.iterations == 3 and not cfg.refine
    assert not UPSRConfig.from_options(2, 5, deblur=False).deblur.enabled


@pytest.mark.parametrize(
    "kwargs",
    [
        {"scale": 0},
        {"scale": -2},
        {"scale": 2.5},
        {"scale": 2, "n_frames": 0},
        {"scale": 2, "n_frames": -3},
        {"scale": 2, "depth_range_mm": (500.0, 100.0)},
        {"scale": 2, "min_valid_fraction": 1.0},
        {"scale": 2, "flow_preset": "slow"},
        {"scale": 2, "trust_noise_profile": "quadratic"},
        {"scale": 2, "trust_noise_profile": (2.0,)},
        {"scale": 2, "trust_noise_profile": (-1.0, 2.0)},
        {"scale": 2, "trust_noise_profile": (2.0, 9.0)},
        {"scale": 2, "trust_noise_profile": (float("nan"), 2.0)},
        {"scale": 2, "trust_noise_profile": None},
        {"scale": 2, "thin_parts": "yes"},
        {"scale": 2, "edge_votes": 1},
    ],
)
def test_bad_parameters_rejected(kwargs):
    with pytest.raises(InputError):
        UPSRConfig(**kwargs)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"lam": -1},
        {"alpha": 0},
        {"alpha": 1.5},
        {"radius_px": 0},
        {"blur": "motion"},
        {"iterations": -1},
        {"step_mm": 0},
        {"step_decay": 0},
        {"edge_mm": -5},
    ],
)
def test_bad_deblur_parameters_rejected(kwargs):
    with pytest.raises(InputError):
        DeblurConfig(**kwargs)


def test_unknown_option_rejected():
    with pytest.raises(InputError, match="unknown option"):
        UPSRConfig.from_options(2, 9, nonsense=1)
    with pytest.raises(InputError, match="unknown deblur option"):
        UPSRConfig.from_options(2, 9, deblur_nonsense=1)


def test_flow_grid_scale_and_residual_preset_follow_the_frame_width():
    from upsr.method.config import FLOW_GRID_MIN_WIDTH_PX

    cfg = UPSRConfig(scale=4)
    assert cfg.flow_grid_scale(64) == 3  # ToF 64 px wide: a 192 px grid
    assert cfg.flow_grid_scale(40) == 4  # never more than r
    assert cfg.flow_grid_scale(256) == 2  # at least 2 (sub-pixel motion, paper eq. 9–12)
    assert UPSRConfig(scale=1).flow_grid_scale(64) == 1
    assert UPSRConfig(scale=2).flow_grid_scale(64) == 2
    assert UPSRConfig(scale=4, flow_scale=3).flow_grid_scale(640) == 3
    assert cfg.residual_flow_preset(FLOW_GRID_MIN_WIDTH_PX) == "ultrafast"
    assert cfg.residual_flow_preset(FLOW_GRID_MIN_WIDTH_PX - 1) == cfg.flow_preset
    assert UPSRConfig(refine_preset="fast").residual_flow_preset(10) == "fast"


def test_speckle_size_is_one_lowres_pixel_by_default():
    assert UPSRConfig(scale=4).speckle_size_px == 16
    assert UPSRConfig(scale=4, speckle_px=0).speckle_size_px == 0
    assert UPSRConfig(scale=2, speckle_px=9).speckle_size_px == 9


@pytest.mark.parametrize(
    "options",
    [
        {"flow_scale": 0},
        {"flow_scale": 5},
        {"flow_scale": 1.5},
        {"refine_preset": "slow"},
        {"speckle_px": -1},
        {"speckle_px": 2.5},
    ],
)
def test_bad_flow_grid_options_are_rejected(options):
    with pytest.raises(InputError):
        UPSRConfig(scale=4, **options)


@pytest.mark.parametrize("bad", [(3000, 100), (-1, 5), (0, float("inf")), "x", (1, 2, 3)])
def test_valid_range_checked(bad):
    with pytest.raises(InputError, match="valid_range_mm"):
        UPSRConfig(valid_range_mm=bad)
    assert UPSRConfig(valid_range_mm=[100, 5000]).valid_range_mm == (100.0, 5000.0)


def test_flags_must_be_bools_and_deblur_a_config_a_mapping_or_a_bool():
    """A flag given as a string was taken as true (``deblur_enabled="no"`` deblurred), a dict
    of deblurring options was taken as "enabled" and its options dropped."""
    for bad in ({"refine": "no"}, {"fill_holes": 1}, {"deblur_enabled": "no"}):
        with pytest.raises(InputError, match="must be True or False"):
            UPSRConfig.from_options(2, 3, **bad)
    with pytest.raises(InputError, match="deblur must be a DeblurConfig"):
        UPSRConfig.from_options(2, 3, deblur="yes")
    as_mapping = UPSRConfig.from_options(2, 3, deblur={"lam": 0.3, "iterations": 4})
    assert (
        as_mapping.deblur
        == UPSRConfig.from_options(2, 3, deblur_lam=0.3, deblur_iterations=4).deblur
    )
    assert UPSRConfig.from_options(2, 3, deblur=False).deblur.enabled is False
    with pytest.raises(InputError, match="unknown deblur option"):
        UPSRConfig.from_options(2, 3, deblur={"lamda": 0.3})


def test_super_resolve_refuses_arguments_that_disagree_with_its_config():
    video = np.full((3, 6, 6), 1500.0, np.float32)
    cfg = UPSRConfig(scale=2, n_frames=3)
    assert upsr.super_resolve(video, 2, config=cfg).shape == (3, 12, 12)
    assert upsr.super_resolve(video, 2, 3, config=cfg).shape == (3, 12, 12)
    # (n_frames=9, the default, beside a config of N = 3 ran with N = 3 without a word)
    for kwargs in (
        {"scale": 4},
        {"scale": 2, "n_frames": 5},
        {"scale": 2, "n_frames": 9},
        {"scale": 2, "mode": "recursive"},
    ):
        with pytest.raises(InputError, match="give the options in the config"):
            upsr.super_resolve(video, config=cfg, **kwargs)


@pytest.mark.parametrize("mode", ["windowed", "recursive"])
def test_the_engines_refuse_arguments_that_disagree_with_their_config(mode):
    """UPSR(scale=3, n_frames=5, config=<r = 2>, deblur_iterations=50) ran with r = 2, N = 9
    and 15 iterations without a word; super_resolve refused the same call."""
    cfg = UPSRConfig(scale=2, mode=mode)
    for kwargs in ({"scale": 3}, {"n_frames": 5}, {"deblur_iterations": 50}, {"flow": "farneback"}):
        with pytest.raises(InputError, match="give the options in the config"):
            upsr.UPSR(config=cfg, **kwargs)
    assert upsr.UPSR(config=cfg).config == cfg
    assert upsr.UPSR(2, config=cfg).config == cfg
    assert upsr.UPSR(config=UPSRConfig(scale=4, mode=mode)).config.scale == 4
    assert upsr.UPSR().config.scale == 2 and upsr.UPSR().config.n_frames == 9
    with pytest.raises(InputError, match="scale r must be"):
        upsr.UPSR(0)


def test_sequence_fields_are_normalised_to_tuples():
    """depth_range_mm / trust_noise_profile given as lists were kept as lists: the config was
    unhashable and unequal to the same one given tuples (valid_range_mm was normalised)."""
    a = UPSRConfig(scale=2, depth_range_mm=[500, 3000], trust_noise_profile=[2, 1.5])
    b = UPSRConfig(scale=2, depth_range_mm=(500.0, 3000.0), trust_noise_profile=(2.0, 1.5))
    assert a == b and hash(a) == hash(b)
    assert a.depth_range_mm == (500.0, 3000.0) and a.trust_noise_profile == (2.0, 1.5)
