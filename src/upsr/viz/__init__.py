"""Pictures of depth: colour maps, comparison pictures, 3-D views, animations, figures."""

from upsr._lazy import attach

__getattr__, __dir__, __all__ = attach(
    __name__,
    submodules=["animation", "colormaps", "figures", "pictures"],
    names={
        "colorize_depth": "colormaps",
        "colorize_error": "colormaps",
        "write_png": "colormaps",
        "comparison_frame": "pictures",
        "ComparisonWriter": "pictures",
        "render_view": "pictures",
    },
)
