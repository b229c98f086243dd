"""The UP-SR method: one module per step of the paper's Table 1, and the engines.

========================  =====================  ==========================================
step                      paper                  module
========================  =====================  ==========================================
dense upsampling U        eq. 13–15              :mod:`upsr.method.upsampling`
prefilter, flow           §4, §5.2, eq. 16–17    :mod:`upsr.method.motion`
motion front-end          §4, §5.2, eq. 16–19    :mod:`upsr.method.frontend`
cumulative registration   eq. 18–21              :mod:`upsr.method.registration`
registration check        —                      :mod:`upsr.method.consistency`
footprint sensor (ToF)    —                      :mod:`upsr.method.footprint`
mixed (flying) pixels     —                      :mod:`upsr.method.mixed`
thin parts (ToF)          —                      :mod:`upsr.method.thin`
clusters of like mixes    —                      :mod:`upsr.method.clusters`
sample trust              —                      :mod:`upsr.method.trust`
surfaces at an edge       —                      :mod:`upsr.method.alternatives`
state memory per pixel    —                      :mod:`upsr.method.memory`
temporal median           eq. 26–28              :mod:`upsr.method.fusion`
L1 + BTV deblurring       eq. 29–30              :mod:`upsr.method.deblurring`
noise estimate            —                      :mod:`upsr.method.noise`
per-video choices         —                      :mod:`upsr.method.statistics`
surface smoothing         —                      :mod:`upsr.method.smoothing`
speckle removal           —                      :mod:`upsr.method.outliers`
sliding-window engine     Table 1                :mod:`upsr.method.windowed`
recursive (causal) engine —                      :mod:`upsr.method.recursive`
its state's update        —                      :mod:`upsr.method.state_update`
warm-up before a stream   —                      :mod:`upsr.method.warmup`
========================  =====================  ==========================================

The method imports nothing from the layers above it (I/O, pictures, research, apps).
"""

from upsr._lazy import attach

__getattr__, __dir__, __all__ = attach(
    __name__,
    submodules=[
        "alternatives",
        "clusters",
        "config",
        "consistency",
        "deblurring",
        "footprint",
        "frontend",
        "fusion",
        "memory",
        "mixed",
        "motion",
        "noise",
        "outliers",
        "recursive",
        "registration",
        "resources",
        "smoothing",
        "state_update",
        "statistics",
        "thin",
        "trust",
        "upsampling",
        "validation",
        "warmup",
        "windowed",
    ],
    names={
        "UPSR": "windowed",
        "super_resolve": "windowed",
        "UPSRConfig": "config",
        "DeblurConfig": "config",
        "deblur": "deblurring",
        "estimate_noise_mm": "noise",
        "MotionFrontEnd": "frontend",
        "temporal_median": "fusion",
        "remove_speckles": "outliers",
        "upsample_nearest": "upsampling",
        "decimate": "upsampling",
    },
)
