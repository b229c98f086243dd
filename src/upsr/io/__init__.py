"""Depth video files: one module per format behind one reader/writer interface.

Every command reads through :func:`probe`, :func:`iter_frames` and :func:`read_video` and
writes through :class:`VideoWriter`, frame by frame; the format follows the name or is
forced. Depth is returned in millimetres (float32, 0 = no measurement).
"""

from upsr._lazy import attach

__getattr__, __dir__, __all__ = attach(
    __name__,
    submodules=[
        "datasets",
        "exr",
        "npy",
        "npz",
        "png",
        "pointcloud",
        "registry",
        "rosbag",
        "tiff",
        "video",
    ],
    names={
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
