"""Research code: SPEC §6 metrics, the paper's baselines, synthetic data, the paper's
experiments, the statistical analysis of the fusion and the NumPy oracle of the method."""

from upsr._lazy import attach

__getattr__, __dir__, __all__ = attach(
    __name__,
    submodules=["analysis", "baselines", "experiments", "metrics", "oracle", "synth"],
)
