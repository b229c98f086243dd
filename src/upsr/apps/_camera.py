"""The camera (intrinsics) of an input video: one look-up for every command.

``--intrinsics FX,FY,CX,CY`` when given, else the intrinsics the input carries (a bag's
``sensor_msgs/CameraInfo``, RealSense's camera info, or an ``INPUT.intrinsics.json``), else
none. Used by ``upsr run``, ``upsr view``, ``upsr export-ply`` and
:func:`upsr.apps.batch.run_batch`; :func:`camera_motion_config` gives ``--camera-motion
depth`` those intrinsics (``upsr run``, ``upsr batch``, ``upsr live``).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

from upsr.errors import InputError
from upsr.method.config import UPSRConfig

__all__ = ["camera_motion_config", "input_camera", "intrinsics_sidecar"]


def camera_motion_config(cfg: UPSRConfig, camera: Any, where: str = "") -> UPSRConfig:
    """``cfg`` registering the frames by the camera's own motion (``camera_motion="depth"``)
    with ``camera``'s intrinsics: a :class:`~upsr.geometry.camera.PinholeCamera` or
    (fx, fy, cx, cy).

    Raises
    ------
    InputError
        ``camera`` is None (one line, prefixed by ``where``).
    """
    if camera is None:
        raise InputError(
            f"{where}--camera-motion depth needs the camera's intrinsics: --intrinsics "
            "FX,FY,CX,CY or intrinsics carried by the input"
        )
    from upsr.geometry.camera import PinholeCamera

    c = camera
    intr = (c.fx, c.fy, c.cx, c.cy) if isinstance(c, PinholeCamera) else tuple(c)
    return dataclasses.replace(cfg, camera_motion="depth", camera_intrinsics=intr)


def input_camera(
    path: Path, info: Any, intrinsics: str | None, *, fmt: str | None, topic: str | None
) -> Any:
    """The :class:`~upsr.geometry.camera.PinholeCamera` of the video at ``path``, or None.

    Parameters
    ----------
    path : pathlib.Path
        The input video.
    info : upsr.io.VideoInfo
        What :func:`upsr.io.probe` found (``width``, ``height`` in px).
    intrinsics : str or None
        ``"fx,fy,cx,cy"`` in px, or a ``.json`` file of them (``--intrinsics``,
        :func:`upsr.geometry.intrinsics.parse_intrinsics`); it wins over what the input
        carries.
    fmt, topic : str or None
        Read options of the input (``--input-format``, ``--topic``).

    Raises
    ------
    InputError
        Bad ``intrinsics``, or carried intrinsics made for another image size.
    """
    from upsr.geometry.intrinsics import parse_intrinsics
    from upsr.io import video as io

    if intrinsics is not None:
        return parse_intrinsics(intrinsics, info.width, info.height)
    cam = io.read_intrinsics(path, fmt=fmt, topic=topic)
    if cam is not None and cam.shape != (info.height, info.width):
        raise InputError(
            f"{path}: its intrinsics are for {cam.width}x{cam.height} images, the frames are "
            f"{info.width}x{info.height}"
        )
    return cam


def intrinsics_sidecar(
    camera: Any, scale: int, stamps: Any = None, names: list[str] | None = None
) -> str | None:
    """The text of ``OUTPUT.intrinsics.json`` for an output super-resolved by ``scale`` from
    frames of ``camera`` (None without intrinsics), with the frames' timestamps (ns) and
    names where known (``upsr run``, ``upsr batch``, ``upsr live``)."""
    if camera is None:
        return None
    from upsr.geometry.intrinsics import intrinsics_text

    return intrinsics_text(
        camera.scaled(scale), source=camera, scale=scale, timestamps_ns=stamps, frame_names=names
    )
