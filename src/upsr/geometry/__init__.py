"""Camera geometry: the pinhole camera, intrinsics scaling (SPEC §1), rendering of meshes,
reprojection of depth between views, a camera's rigid motion between depth frames."""

from upsr._lazy import attach, by_module

__getattr__, __dir__, __all__ = attach(
    __name__,
    submodules=["camera", "intrinsics", "rendering", "reprojection", "rigid"],
    names=by_module(
        camera=["PinholeCamera"],
        rendering=["look_at", "render_depth"],
        reprojection=["reproject"],
        rigid=["rigid_motion"],
        intrinsics=["parse_intrinsics", "scale_intrinsics", "load_intrinsics", "write_intrinsics"],
    ),
)
