"""``upsr export-ply``: a coloured PLY point cloud per frame of a depth video."""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from upsr.apps._preflight import read_options
from upsr.apps.cli.options import (
    DepthScaleOpt,
    InFormatOpt,
    IntrinsicsOpt,
    KeyOpt,
    OverwriteOpt,
    QuietOpt,
    TopicOpt,
    fmt,
)
from upsr.errors import InputError

if TYPE_CHECKING:
    import numpy as np

__all__ = ["export_ply", "register"]


def _colour_source(color: Path | None, n: int) -> list[Path | None]:
    if color is None:
        return [None] * n
    from upsr.io._common import frame_files

    suffixes = (".png", ".jpg", ".jpeg", ".ppm", ".pgm", ".bmp", ".tif", ".tiff")
    if not color.exists():
        raise InputError(f"--color {color}: no such file or folder")
    files = frame_files(color, suffixes, "colour image")
    if len(files) == 1 and n > 1 and not color.is_dir():
        return [files[0]] * n
    if len(files) != n:
        raise InputError(f"--color {color}: {len(files)} colour images for {n} depth frames")
    return list(files)


def _read_colour(path: Path) -> np.ndarray:
    import cv2
    import numpy as np

    data = np.fromfile(path, np.uint8) if path.is_file() else None
    img = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data is not None and data.size else None
    if img is None:
        raise InputError(f"{path}: cannot read the colour image")
    return img


def export_ply(
    input_path: Annotated[Path, typer.Argument(metavar="INPUT", help="Depth video.")],
    out: Annotated[
        Path, typer.Option("--out", "-o", show_default=False, help="Folder for the PLY files.")
    ],
    intrinsics: IntrinsicsOpt = None,
    color: Annotated[
        Path | None,
        typer.Option(
            "--color",
            help="Colour image (all frames) or folder of images (one per frame, name order), "
            "registered to the depth; resized to the depth's size [default: depth colours].",
        ),
    ] = None,
    key: KeyOpt = None,
    topic: TopicOpt = None,
    input_format: InFormatOpt = None,
    depth_scale: DepthScaleOpt = None,
    overwrite: OverwriteOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Write a coloured point cloud per frame: OUT/frame_000000.ply, ...

    Binary PLY, points in metres in the camera frame (x right, y down, z forward); pixels
    without depth are skipped.
    """
    from upsr._atomic import new_temp_dir, remove
    from upsr.apps._camera import input_camera
    from upsr.io import video as io
    from upsr.io.paths import check_apart_from_inputs
    from upsr.io.registry import require

    require("plyfile", "writing PLY point clouds")
    read = read_options(key, topic, fmt(input_format), depth_scale, [input_path])
    info = io.probe(input_path, key=key, fmt=read["fmt"], topic=topic)
    cam = input_camera(input_path, info, intrinsics, fmt=read["fmt"], topic=topic)
    if cam is None:
        raise InputError(
            f"{input_path}: no camera intrinsics in the file: give --intrinsics FX,FY,CX,CY"
        )
    colours = _colour_source(color, info.n_frames)
    check_apart_from_inputs([input_path] + ([color] if color is not None else []), out)
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out} exists and is not a folder")
    names = [f"frame_{t:06d}.ply" for t in range(info.n_frames)]
    existing = [out / n for n in names if (out / n).exists()]
    if existing and not overwrite:
        raise InputError(f"{existing[0]} already exists (use --overwrite to replace)")
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = new_temp_dir(out)  # every file first, then published: a failure leaves nothing
    try:
        points = _write_frames(io.iter_frames(input_path, **read), tmp, names, cam, colours,
                               read["depth_scale"], (str(input_path), quiet))  # fmt: skip
        _publish_files(tmp, out, names)
    finally:
        remove(tmp)
    typer.echo(f"upsr: export-ply: {info.n_frames} PLY file(s), {points} points -> {out}")


def _publish_files(tmp: Path, out: Path, names: list[str]) -> None:
    """Move the complete folder ``tmp`` to ``out`` (a new folder), or its files into the
    existing folder ``out`` (replacing those of an earlier export: --overwrite)."""
    from upsr._atomic import publish

    if not out.exists():
        publish(tmp, out, replace=False)
        return
    for name in names:
        os.replace(tmp / name, out / name)


def _write_frames(
    frames: Iterator[np.ndarray], folder: Path, names: list[str], cam: Any,
    colours: list[Path | None], depth_scale: float, label: tuple[str, bool],
) -> int:  # fmt: skip
    """Write each frame's PLY file into ``folder``; the number of points."""
    import numpy as np
    from tqdm import tqdm

    from upsr.io import units
    from upsr.io.pointcloud import write_ply
    from upsr.viz.pointcloud_colors import color_for_depth

    name, quiet = label
    vmin = vmax = None
    points = 0
    with tqdm(total=len(names), desc="export-ply", file=sys.stderr, disable=quiet) as bar:
        checked = False
        for t, depth in enumerate(frames):
            if not checked and (depth > 0).any():  # (a metres file read as mm: 1000× small)
                units.check_depth_range(depth, depth_scale=depth_scale, name=name,
                                        option="--depth-scale")  # fmt: skip
                checked = True
            src = colours[t]
            if src is None and vmin is None:
                vals = depth[depth > 0]
                lo, hi = np.percentile(vals, [1, 99]) if vals.size else (0.0, 1000.0)
                vmin, vmax = float(lo), float(max(hi, lo + 1.0))
            col = color_for_depth(
                depth, _read_colour(src) if src is not None else None, vmin_mm=vmin, vmax_mm=vmax
            )
            write_ply(folder / names[t], depth, cam, col)
            points += int((depth > 0).sum())
            bar.update(1)
    return points


def register(app: typer.Typer) -> None:
    """Add ``export-ply`` to the ``upsr`` app."""
    app.command(
        "export-ply",
        epilog="\b\nExample:\n  upsr export-ply out.npy -o ply/ --intrinsics 1050,1050,639.5,479.5",
        no_args_is_help=True,
    )(export_ply)
