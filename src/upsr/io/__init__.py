"""Depth video files: one module per format behind one reader/writer interface.

Every command reads through :func:`probe`, :func:`iter_frames` and :func:`read_video` and
writes through :class:`VideoWriter`, frame by frame; the format follows the name or is
forced. Depth is returned in millimetres (float32, 0 = no measurement).
"""

from upsr._lazy import attach, by_module

#: The format modules (each: probe, frames and, if writable, a FrameSink) and helpers.
_MODULES = """color datasets exr identity npy npz paths png pointcloud registry rosbag tiff units
video"""
#: The reader/writer interface every command uses (defined in :mod:`upsr.io.video`).
_API = """FORMATS WRITE_FORMATS VideoInfo VideoWriter intrinsics_path
iter_frames probe read_intrinsics read_video write_bytes_atomic write_text_atomic write_video"""

__getattr__, __dir__, __all__ = attach(
    __name__,
    submodules=_MODULES.split(),
    names=by_module(
        video=_API.split(),
        paths=["check_output_path"],
        identity=["read_timestamps", "read_frame_names"],
        color=["resample_color", "write_color"],
        units=[
            "check_depth_range",
            "check_output_capacity",
            "detect_sun_packing",
            "detect_tum_scale",
            "resolve_depth_scales",
        ],
    ),
)
