"""upsr.apps.cli.options: one definition of the options ``upsr run`` and ``upsr batch`` share."""

from __future__ import annotations

import dataclasses

import typer

from upsr.apps.batch import _OUT_SUFFIX
from upsr.apps.cli.main import app
from upsr.apps.cli.options import (
    DEFAULT_FRAMES,
    HELP_DEFAULTS,
    Blur,
    Flow,
    FlowPreset,
    OutFormat,
    config_from_options,
)
from upsr.method.config import DeblurConfig, UPSRConfig

METHOD_OPTIONS = {
    "--scale",
    "--frames",
    "--no-deblur",
    "--lam",
    "--alpha",
    "--btv-radius",
    "--iterations",
    "--blur",
    "--flow",
    "--flow-preset",
    "--flow-scale",
    "--refine-preset",
    "--speckle-px",
    "--smooth-mm",
    "--no-refine",
    "--keep-all-motion",
    "--fill-holes",
    "--trust-k",
    "--no-trust",
    "--fusion-estimator",
    "--noise-model",
    "--mixed-removal",
    "--no-registration-check",
    "--no-radial",
    "--no-slopes",
    "--no-edge-votes",
    "--no-thin-parts",
}
READ_OPTIONS = {
    "--key",
    "--topic",
    "--input-format",
    "--depth-scale",
    "--input-depth-scale",
    "--output-depth-scale",
    "--intrinsics",
    "--keep-names",
    "--sensor",
    "--strict-units",
    "--max-memory",
}


def _params(name: str) -> dict[str, object]:
    command = typer.main.get_command(app).commands[name]  # type: ignore[attr-defined]
    return {p.opts[-1] if p.opts[-1].startswith("--") else p.opts[0]: p for p in command.params}


def test_help_shows_the_config_defaults() -> None:
    cfg, deblur = UPSRConfig(), DeblurConfig()
    for name, shown in HELP_DEFAULTS.items():
        obj, attr = (deblur, name.split(".")[1]) if name.startswith("deblur.") else (cfg, name)
        assert getattr(obj, attr) == shown, name
    assert UPSRConfig.from_options(2, DEFAULT_FRAMES) == config_from_options(2, None)


def test_run_and_batch_share_one_definition_of_the_method_options() -> None:
    run, batch = _params("run"), _params("batch")
    assert METHOD_OPTIONS | READ_OPTIONS <= set(run) & set(batch)
    for opt in METHOD_OPTIONS | READ_OPTIONS:
        a, b = run[opt], batch[opt]
        same = ("opts", "help", "default", "min", "max", "metavar", "is_flag")
        if opt == "--frames":  # (batch has no --recursive: its help says nothing of it)
            same = same[:1] + same[2:]
            assert b.help.rstrip(".") in a.help and "--recursive" not in b.help
        assert [getattr(a, k) for k in same] == [getattr(b, k) for k in same], opt
        assert a.type_descriptor.annotation is b.type_descriptor.annotation, opt
    assert run["--format"].type_descriptor.annotation is OutFormat
    assert batch["--format"].type_descriptor.annotation is OutFormat


def test_choices_are_what_the_config_and_the_writers_accept() -> None:
    assert {f.value for f in OutFormat} == set(_OUT_SUFFIX)
    for blur in Blur:
        assert DeblurConfig(blur=blur.value).blur == blur.value
    for flow in Flow:
        assert UPSRConfig(flow=flow.value).flow == flow.value
    for preset in FlowPreset:
        assert UPSRConfig(flow_preset=preset.value).flow_preset == preset.value


def test_config_from_options_maps_every_option() -> None:
    cfg = config_from_options(
        3,
        5,
        lam=0.25,
        alpha=0.5,
        btv_radius=3,
        iterations=4,
        blur=Blur.box,
        flow=Flow.farneback,
        flow_preset=FlowPreset.fast,
        flow_scale=2,
        refine_preset=FlowPreset.ultrafast,
        speckle_px=0,
        no_refine=True,
        keep_all_motion=True,
    )
    d = cfg.deblur
    assert (d.enabled, d.lam, d.alpha, d.radius_px, d.iterations, d.blur) == (
        True,
        0.25,
        0.5,
        3,
        4,
        "box",
    )
    assert (cfg.scale, cfg.n_frames, cfg.flow, cfg.flow_preset, cfg.flow_scale) == (
        3,
        5,
        "farneback",
        "fast",
        2,
    )
    assert (cfg.refine_preset, cfg.speckle_size_px, cfg.refine) == ("ultrafast", 0, False)
    assert cfg.zero_motion_tolerance is None
    assert not config_from_options(2, None, no_deblur=True).deblur.enabled
    assert config_from_options(2, None, smooth_mm=12.0).deblur.smooth_sigma_mm == 12.0
    assert config_from_options(2, None, smooth_mm=0.0).deblur.smooth_sigma_mm is None
    assert dataclasses.replace(config_from_options(2, None), n_frames=9) == UPSRConfig.from_options(
        2, 9
    )


def test_edge_mm_sets_the_fusions_and_the_deblurrings_step(tmp_path, capsys) -> None:
    """--edge-mm MM: one depth step between surfaces for the fusion and the deblurring (a camera
    at close range); the same output as the API given both; a bad value is one line."""
    import numpy as np

    import upsr
    from tests.apps._util import run_cli
    from upsr.apps.cli.options import config_from_options

    cfg = config_from_options(2, 3, edge_mm=12.5)
    assert cfg.edge_mm == cfg.deblur.edge_mm == 12.5 and cfg.near_depth_mm is None
    rng = np.random.default_rng(0)
    xs = np.mgrid[0:20, 0:24][1].astype(np.float32)
    video = np.stack([200 + xs + rng.normal(0, 1, xs.shape) for _ in range(4)]).astype(np.float32)
    video[:, 6:14, 8:16] -= 30.0  # (a box 30 mm in front: one surface at the default 100 mm)
    np.save(tmp_path / "in.npy", video)
    rc, _, err = run_cli(capsys, "run", tmp_path / "in.npy", "-o", tmp_path / "o.npy", "-r", "2",
                         "-n", "3", "-q", "--edge-mm", "12.5")  # fmt: skip
    assert rc == 0, err
    want = upsr.super_resolve(video, 2, 3, edge_mm=12.5, deblur_edge_mm=12.5, near_depth_mm=None)
    np.testing.assert_array_equal(np.load(tmp_path / "o.npy"), want)
    assert not np.array_equal(want, upsr.super_resolve(video, 2, 3, near_depth_mm=None))
    for bad in ("0", "-3", "nan"):
        rc, _, err = run_cli(capsys, "run", tmp_path / "in.npy", "-o", tmp_path / "b.npy", "-r",
                             "2", "--edge-mm", bad)  # fmt: skip
        assert rc == 2 and "--edge-mm must be a number > 0" in err, err


def test_smooth_mm_sets_or_turns_off_the_final_smoothing(tmp_path, capsys) -> None:
    """--smooth-mm MM: the final smoothing's range std (0: off); the same output as the API
    given it; a bad value is one line."""
    import numpy as np

    import upsr
    from tests.apps._util import run_cli

    rng = np.random.default_rng(1)
    ys, xs = np.mgrid[0:20, 0:24].astype(np.float32)
    video = np.stack([1500 + 20 * ys + rng.normal(0, 5, xs.shape) for _ in range(4)])
    np.save(tmp_path / "in.npy", video.astype(np.float32))
    for value, smooth in (("0", None), ("12.5", 12.5)):
        rc, _, err = run_cli(capsys, "run", tmp_path / "in.npy", "-o", tmp_path / "o.npy", "-r",
                             "2", "-n", "3", "-q", "--overwrite", "--smooth-mm", value)  # fmt: skip
        assert rc == 0, err
        want = upsr.super_resolve(video, 2, 3, deblur_smooth_sigma_mm=smooth)
        np.testing.assert_array_equal(np.load(tmp_path / "o.npy"), want)
    assert not np.array_equal(want, upsr.super_resolve(video, 2, 3, deblur_smooth_sigma_mm=None))
    for bad in ("-3", "nan"):
        rc, _, err = run_cli(capsys, "run", tmp_path / "in.npy", "-o", tmp_path / "b.npy", "-r",
                             "2", "--smooth-mm", bad)  # fmt: skip
        assert rc == 2 and "--smooth-mm" in err and "Traceback" not in err, err
