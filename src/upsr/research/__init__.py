"""Research code: SPEC §6 metrics, the paper's baselines, synthetic data, the paper's
experiments, the statistical analysis of the fusion, the NumPy oracle of the method and
simple peers (per-frame bilateral, temporal mean)."""

from upsr._lazy import attach

__getattr__, __dir__, __all__ = attach(
    __name__,
    submodules=["analysis", "baselines", "experiments", "metrics", "oracle", "peers", "synth"],
)
