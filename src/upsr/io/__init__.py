"""Depth video files: one module per format behind one reader/writer interface.

Every command reads through :func:`probe`, :func:`iter_frames` and :func:`read_video` and
writes through :class:`VideoWriter`, frame by frame; the format follows the name or is
forced. Depth is returned in millimetres (float32, 0 = no measurement).
"""

from upsr._lazy import attach

__getattr__, __dir__, __all__ = attach(
    __name__,
    submodules=[
        "color",
        "datasets",
        "exr",
        "identity",
        "npy",
        "npz",
        "png",
        "pointcloud",
        "registry",
        "rosbag",
        "tiff",
        "units",
        "video",
    ],
    names={
        "read_timestamps": "identity",
        "read_frame_names": "identity",
        "resample_color": "color",
        "write_color": "color",
        "check_depth_range": "units",
        "check_output_capacity": "units",
        "detect_tum_scale": "units",
        "resolve_depth_scales": "units",
    }
    | {
        name: "video"
        for name in (
            "FORMATS",
            "WRITE_FORMATS",
            "VideoInfo",
            "VideoWriter",
            "check_output_path",
            "intrinsics_path",
            "iter_frames",
            "probe",
            "read_intrinsics",
            "read_video",
            "write_bytes_atomic",
            "write_text_atomic",
            "write_video",
        )
    },
)
