"""The methods the paper compares UP-SR against (paper §7.3–7.4, Fig. 3–6), by kind.

Single frame (:mod:`upsr.research.baselines.single_frame`)
    :func:`nearest` (dense upsampling U on its own), :func:`bicubic` (naive), and
    :func:`bicubic_noflying` (bicubic with the flying pixels removed by a fixed threshold, §7.4);
    :func:`joint_bilateral_upsampling` (Kopf et al. 2007, the "2-D/depth fusion" of Fig. 4 (c)),
    guided by a high-res colour or grey image.
Learned, single frame (:mod:`upsr.research.baselines.learned`)
    :func:`patch_sisr` / :class:`PatchSISR` / :func:`train_patch_sisr` (example-based
    single-image SR after Mac Aodha et al. 2012, "patch-based SISR" [12]).
Multi-frame, with the motion of UP-SR (:mod:`upsr.research.baselines.multi_frame`)
    :func:`shift_add` (dynamic median Shift & Add, Farsiu et al. 2004, "dynamic S&A" [41]) and
    :func:`lidarboost` (Schuon et al. 2009). Both use the consecutive flows between *upsampled*
    frames that UP-SR estimates (:func:`upsampled_flows`, paper §4, §5.2: the engine's
    :class:`upsr.method.frontend.MotionFrontEnd`), chained by composition
    (:mod:`upsr.method.registration`); precomputed flows may be passed instead.

Everything uses the pixel geometry of ``SPEC.md`` §1: low-res pixel (i, j) sits at high-res
coordinate ((i + 0.5)·r − 0.5, (j + 0.5)·r − 0.5). Depth is float32 mm, 0 = unknown. The
names are loaded lazily (PEP 562).
"""

from upsr._lazy import attach, by_module

__getattr__, __dir__, __all__ = attach(
    __name__,
    submodules=["learned", "multi_frame", "single_frame"],
    names=by_module(
        single_frame=["nearest", "bicubic", "bicubic_noflying", "joint_bilateral_upsampling"],
        multi_frame=["FlowPair", "upsampled_flows", "shift_add", "lidarboost"],
        learned=["PatchSISR", "train_patch_sisr", "patch_sisr"],
    ),
)
