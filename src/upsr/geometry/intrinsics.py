"""Camera intrinsics of depth videos: parse, scale to the output resolution, read and write.

A camera is an :class:`upsr.geometry.camera.PinholeCamera` (fx, fy, cx, cy in px, width, height),
with the pixel geometry of ``SPEC.md`` §1: pixel (i, j) is centred at image coordinates
(u, v) = (j, i), the convention of OpenCV and of ROS ``CameraInfo``. Super-resolving by r keeps
the field of view: f' = r·f and c' = r·(c + 0.5) − 0.5 (:meth:`PinholeCamera.scaled`).

The intrinsics of an output video are written next to it as ``<output>.intrinsics.json``::

    {"width": 1280, "height": 960, "fx": 1050.0, "fy": 1050.0, "cx": 639.5, "cy": 479.5,
     "K": [[...], [...], [...]], "intrinsic_matrix": [9 values, K column-major], "scale": 2,
     "timestamps_ns": [...], "frame_names": [...],
     "input": {"width": 640, "height": 480, "fx": 525.0, ...}, "convention": "..."}
"""

from __future__ import annotations

import json
import math
import os
import stat
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from upsr.errors import InputError, one_line
from upsr.geometry.camera import PinholeCamera

__all__ = [
    "CONVENTION",
    "PinholeCamera",
    "camera_from_dict",
    "camera_to_dict",
    "intrinsics_text",
    "load_intrinsics",
    "parse_intrinsics",
    "scale_intrinsics",
    "write_intrinsics",
]

#: The pixel convention stated in every intrinsics file.
#: Largest ``*.intrinsics.json`` read (bytes): a real one is a few hundred bytes.
MAX_INTRINSICS_BYTES = 1 << 20

CONVENTION = (
    "pinhole, no distortion; pixel (row i, column j) centred at (u, v) = (j, i) px; "
    "scaled by r (SPEC 1): f' = r f, c' = r (c + 0.5) - 0.5"
)


def parse_intrinsics(text: str, width: int, height: int) -> PinholeCamera:
    """Parse ``"fx,fy,cx,cy"`` (px) for images of ``width`` × ``height`` px, or read a JSON
    file of them (a name ending in ``.json``: an ``*.intrinsics.json`` of ``upsr run``, or an
    Open3D ``PinholeCameraIntrinsic`` file; :func:`load_intrinsics`), made for that size.

    Raises
    ------
    InputError
        Not four finite numbers, or fx/fy ≤ 0; an unreadable file, or one for images of
        another size.
    """
    if str(text).strip().lower().endswith(".json"):
        camera = load_intrinsics(str(text).strip())
        if (camera.width, camera.height) != (int(width), int(height)):
            raise InputError(
                f"{text}: intrinsics of {camera.width}x{camera.height} images, the input's "
                f"frames are {width}x{height}"
            )
        return camera
    parts = [p.strip() for p in str(text).replace(";", ",").split(",")]
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = []
    if len(values) != 4 or not all(math.isfinite(v) for v in values):
        raise InputError(
            f"--intrinsics must be four numbers fx,fy,cx,cy (px), e.g. 525,525,319.5,239.5; "
            f"got {text!r}"
        )
    fx, fy, cx, cy = values
    return PinholeCamera(fx, fy, cx, cy, int(width), int(height))


def scale_intrinsics(camera: PinholeCamera, scale: int | float) -> PinholeCamera:
    """The camera of the output of super-resolution by ``scale`` (SPEC §1 geometry)."""
    return camera.scaled(scale)


def camera_to_dict(camera: PinholeCamera) -> dict[str, Any]:
    """JSON-ready description: width, height, fx, fy, cx, cy and K."""
    return {
        "width": int(camera.width),
        "height": int(camera.height),
        "fx": float(camera.fx),
        "fy": float(camera.fy),
        "cx": float(camera.cx),
        "cy": float(camera.cy),
        "K": [[float(v) for v in row] for row in camera.K],
        # Open3D's PinholeCameraIntrinsic JSON: K column-major (read_pinhole_camera_intrinsic)
        "intrinsic_matrix": [float(v) for v in np.asarray(camera.K, np.float64).T.reshape(-1)],
    }


def camera_from_dict(d: Any, name: str = "intrinsics") -> PinholeCamera:
    """Inverse of :func:`camera_to_dict` (``K`` is ignored; fx, fy, cx, cy are used), or an
    Open3D ``PinholeCameraIntrinsic`` (width, height and ``intrinsic_matrix``, K column-major)."""
    if not isinstance(d, dict):
        raise InputError(f"{name}: expected a JSON object")
    try:
        w, h = d["width"], d["height"]
        if isinstance(w, bool) or isinstance(h, bool) or int(w) != w or int(h) != h:
            raise ValueError("width and height must be integers")
        if "fx" not in d and "intrinsic_matrix" in d:
            m = [float(v) for v in d["intrinsic_matrix"]]
            if len(m) != 9:
                raise ValueError("intrinsic_matrix must hold 9 numbers")
            return PinholeCamera(m[0], m[4], m[6], m[7], int(w), int(h))
        return PinholeCamera(
            float(d["fx"]), float(d["fy"]), float(d["cx"]), float(d["cy"]), int(w), int(h)
        )
    except InputError as e:
        raise InputError(f"{name}: {e}") from None
    except (KeyError, TypeError, ValueError, OverflowError) as e:
        raise InputError(f"{name}: not an intrinsics file ({type(e).__name__}: {e})") from None


def load_intrinsics(path: str | os.PathLike[str]) -> PinholeCamera:
    """Read an ``*.intrinsics.json`` file (as written by :func:`write_intrinsics`)."""
    p = Path(path)
    try:
        st = os.stat(p)
        if not stat.S_ISREG(st.st_mode):
            raise InputError(f"{p}: not a regular file")
        if st.st_size > MAX_INTRINSICS_BYTES:
            raise InputError(f"{p}: {st.st_size} bytes is too large for an intrinsics file")
        d = json.loads(p.read_text(encoding="utf-8"))
    except OSError as e:
        raise InputError(f"{p}: cannot read ({e.strerror or e})") from None
    except RecursionError:
        raise InputError(f"{p}: not an intrinsics file (JSON nested too deeply)") from None
    except ValueError as e:
        raise InputError(one_line(f"{p}: not a JSON file ({e})")) from None
    return camera_from_dict(d, str(p))


def intrinsics_text(
    camera: PinholeCamera,
    *,
    source: PinholeCamera | None = None,
    scale: int | float | None = None,
    timestamps_ns: Sequence[int] | None = None,
    frame_names: Sequence[str] | None = None,
) -> str:
    """The JSON text :func:`write_intrinsics` writes (e.g. for ``VideoWriter.add_sidecar``)."""
    d = camera_to_dict(camera)
    if scale is not None:
        d["scale"] = scale
    if source is not None:
        d["input"] = camera_to_dict(source)
        d["input"].pop("intrinsic_matrix")
    if timestamps_ns is not None:
        d["timestamps_ns"] = [int(t) for t in timestamps_ns]
    if frame_names is not None:
        d["frame_names"] = [str(n) for n in frame_names]
    d["convention"] = CONVENTION
    return json.dumps(d, indent=2) + "\n"


def write_intrinsics(
    path: str | os.PathLike[str],
    camera: PinholeCamera,
    *,
    source: PinholeCamera | None = None,
    scale: int | float | None = None,
    timestamps_ns: Sequence[int] | None = None,
    frame_names: Sequence[str] | None = None,
) -> Path:
    """Write ``camera`` as JSON atomically (with the input camera and scale, if given).

    The file is also an Open3D ``PinholeCameraIntrinsic`` (``width``, ``height``,
    ``intrinsic_matrix``: K column-major), readable by
    ``open3d.io.read_pinhole_camera_intrinsic``. ``timestamps_ns`` (int ns per frame) and
    ``frame_names`` pair the output frames with the input's (and its colour frames).
    """
    from upsr._atomic import write_text_atomic

    text = intrinsics_text(
        camera, source=source, scale=scale, timestamps_ns=timestamps_ns, frame_names=frame_names
    )
    return write_text_atomic(path, text)
