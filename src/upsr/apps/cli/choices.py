"""The choices of the ``upsr`` commands' options (typer ``Enum`` types).

Importing this module does not import NumPy or the method (``upsr --version`` stays fast).
"""

from __future__ import annotations

from enum import Enum

__all__ = [
    "Blur",
    "CameraMotion",
    "Flow",
    "FlowPreset",
    "FusionEstimator",
    "InFormat",
    "NoiseModel",
    "OutFormat",
    "Sensor",
    "fmt",
]


class InFormat(str, Enum):
    """Input formats of :mod:`upsr.io` (``--input-format``)."""

    npy = "npy"
    npz = "npz"
    png = "png"
    tiff = "tiff"
    exr = "exr"
    rosbag = "rosbag"
    nyu = "nyu"
    pgm = "pgm"
    tum = "tum"
    sun = "sun"


class OutFormat(str, Enum):
    """Output formats (``upsr run --format``, ``upsr batch --format``)."""

    npy = "npy"
    npz = "npz"
    png = "png"
    tiff = "tiff"
    exr = "exr"
    rosbag = "rosbag"


class Sensor(str, Enum):
    """Sensors of :data:`upsr.io.units.SENSOR_RANGES_MM` (``--sensor``)."""

    default = "default"
    realsense = "realsense"
    kinect = "kinect"
    kinect2 = "kinect2"
    tof = "tof"
    lidar = "lidar"


class FusionEstimator(str, Enum):
    auto = "auto"
    median = "median"
    mean = "mean"


class NoiseModel(str, Enum):
    auto = "auto"
    constant = "constant"


class Blur(str, Enum):
    none = "none"
    box = "box"
    gaussian = "gaussian"


class Flow(str, Enum):
    dis = "dis"
    farneback = "farneback"


class FlowPreset(str, Enum):
    ultrafast = "ultrafast"
    fast = "fast"
    medium = "medium"


class CameraMotion(str, Enum):
    flow = "flow"
    depth = "depth"


def fmt(value: Enum | None) -> str | None:
    """The string of a choice, None for none."""
    return None if value is None else str(value.value)
