"""Colour frames on the output grid, for RGB-D hand-offs (Open3D ``create_from_color_and_depth``).

:func:`resample_color` resizes one colour image to the super-resolved depth's (h', w') with the
pixel geometry of SPEC §1 (pixel centres at integer coordinates, the field of view kept: OpenCV's
``resize`` maps output pixel centre x' to input x = (x' + 0.5)/r − 0.5, the same c' = r(c + 0.5) −
0.5 as the intrinsics). :func:`write_color` does it for an image file or a folder of images and
writes lossless PNGs (8 or 16 bit, as the input) into a folder, atomically, keeping the names.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from upsr.errors import InputError
from upsr.io._base import PathLike, natural_key

__all__ = ["COLOR_SUFFIXES", "color_files", "resample_color", "write_color"]

#: Colour image files read.
COLOR_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")


def resample_color(image: np.ndarray, shape_px: tuple[int, int]) -> np.ndarray:
    """``image`` (h, w[, c]) resized to ``shape_px`` = (h', w') (bilinear; area when shrinking).

    The dtype and channels are kept (uint8/uint16 colour or grey).
    """
    import cv2

    img = np.asarray(image)
    if img.ndim not in (2, 3) or img.size == 0:
        raise InputError(f"a colour image must be (h, w) or (h, w, c), got shape {img.shape}")
    h, w = (int(v) for v in shape_px)
    if h < 1 or w < 1:
        raise InputError(f"output grid {shape_px} is empty")
    if img.shape[:2] == (h, w):
        return img.copy()
    shrink = h < img.shape[0] or w < img.shape[1]
    out = cv2.resize(img, (w, h), interpolation=cv2.INTER_AREA if shrink else cv2.INTER_LINEAR)
    return out.reshape((h, w, *img.shape[2:]))


def color_files(src: PathLike) -> list[Path]:
    """An image file as a one-item list, or the colour images of a folder (natural order)."""
    p = Path(src)
    if p.is_file():
        return [p]
    if not p.is_dir():
        raise InputError(f"{p}: no such colour image or folder")
    files = [
        Path(e.path)
        for e in os.scandir(p)
        if e.is_file()
        and not e.name.startswith(".")
        and os.path.splitext(e.name)[1].lower() in COLOR_SUFFIXES
    ]
    if not files:
        raise InputError(f"{p}: no colour images ({', '.join(COLOR_SUFFIXES)}) in this folder")
    return sorted(files, key=lambda f: natural_key(f.name))


def _read(file: Path) -> np.ndarray:
    import cv2

    img = cv2.imread(str(file), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise InputError(f"{file}: not a readable image")
    if img.dtype not in (np.uint8, np.uint16):
        raise InputError(f"{file}: colour images must be 8 or 16 bit, got {img.dtype}")
    return img


def write_color(
    src: PathLike,
    dest: PathLike,
    shape_px: tuple[int, int],
    *,
    n_frames: int | None = None,
    frame_names: Sequence[str] | None = None,
    overwrite: bool = False,
) -> Path:
    """Resample the colour image(s) ``src`` to ``shape_px`` and write them as PNGs in ``dest``.

    Parameters
    ----------
    src : path-like
        An image file or a folder of images (:data:`COLOR_SUFFIXES`), one per depth frame.
    dest : path-like
        The output folder (created atomically: it appears complete or not at all).
    shape_px : (int, int)
        (h', w') of the super-resolved depth.
    n_frames : int, optional
        Depth frames: a different number of colour images is refused.
    frame_names : sequence of str, optional
        Output names without suffix (default: the colour files' stems).
    overwrite : bool
        Replace an existing ``dest`` folder of PNGs.

    Returns
    -------
    pathlib.Path
        ``dest``.
    """
    import cv2

    from upsr._atomic import new_temp_dir, remove
    from upsr.io.identity import check_frame_names

    files = color_files(src)
    if n_frames is not None and len(files) != n_frames:
        raise InputError(
            f"{src}: {len(files)} colour image(s) for {n_frames} depth frame(s): give one "
            f"colour image per depth frame"
        )
    names = check_frame_names(
        [f.stem for f in files] if frame_names is None else frame_names, len(files)
    )
    out = Path(dest)
    if os.path.lexists(out):
        if not overwrite:
            raise InputError(f"output {out} already exists (use --overwrite to replace it)")
        if not out.is_dir() or any(not n.lower().endswith(".png") for n in os.listdir(out)):
            raise InputError(f"refusing to replace {out}: not a folder of PNG files only")
    out.parent.mkdir(parents=True, exist_ok=True)
    temp = new_temp_dir(out)
    try:
        for f, name in zip(files, names, strict=True):
            ok, buf = cv2.imencode(".png", resample_color(_read(f), shape_px))
            if not ok:  # pragma: no cover
                raise InputError(f"{f}: PNG encoding failed")
            (temp / f"{name}.png").write_bytes(buf.tobytes())
        if os.path.lexists(out):
            remove(out)
        os.replace(temp, out)
    except BaseException:
        remove(temp)
        raise
    return out
