"""Synthetic dynamic depth scenes with exact ground truth, and sensor degradations."""

from __future__ import annotations

from upsr.research.synth.degradation import (
    add_depth_dependent_noise,
    add_laplacian_noise,
    dropout,
    flying_pixel_artefacts,
    kinect,
    kinect_axial_sigma_mm,
    projector_shadows,
    quantise_disparity,
    tof_footprint,
)
from upsr.research.synth.realistic import RealisticVideo, degrade, make_realistic
from upsr.research.synth.recording import write_realsense_recording
from upsr.research.synth.scenes import DynamicScene, SyntheticVideo, dynamic_scene, make_scene

__all__ = [
    "DynamicScene",
    "RealisticVideo",
    "SyntheticVideo",
    "add_depth_dependent_noise",
    "add_laplacian_noise",
    "degrade",
    "dropout",
    "dynamic_scene",
    "flying_pixel_artefacts",
    "kinect",
    "kinect_axial_sigma_mm",
    "make_realistic",
    "make_scene",
    "projector_shadows",
    "quantise_disparity",
    "tof_footprint",
    "write_realsense_recording",
]
