"""Camera geometry: the pinhole camera, intrinsics scaling (SPEC §1), rendering of meshes."""

from upsr._lazy import attach

__getattr__, __dir__, __all__ = attach(
    __name__,
    submodules=["camera", "intrinsics", "rendering"],
    names={
        "PinholeCamera": "camera",
        "look_at": "rendering",
        "render_depth": "rendering",
        "parse_intrinsics": "intrinsics",
        "scale_intrinsics": "intrinsics",
        "load_intrinsics": "intrinsics",
        "write_intrinsics": "intrinsics",
    },
)
