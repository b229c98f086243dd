"""Camera geometry: the pinhole camera, intrinsics scaling (SPEC §1), rendering of meshes."""

from upsr._lazy import attach, by_module

__getattr__, __dir__, __all__ = attach(
    __name__,
    submodules=["camera", "intrinsics", "rendering"],
    names=by_module(
        camera=["PinholeCamera"],
        rendering=["look_at", "render_depth"],
        intrinsics=["parse_intrinsics", "scale_intrinsics", "load_intrinsics", "write_intrinsics"],
    ),
)
