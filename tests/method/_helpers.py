"""Shared scenes of the method's tests."""

import numpy as np

#: The wall behind the scenes (mm).
WALL = 3000.0


def tof_edge_frames(n=3, h=12, w=16, r=4):
    """ToF footprints (block means of a high-res step edge at a sub-pixel position)."""
    from upsr.research.synth.degradation import tof_footprint

    hr = np.full((n, h * r, w * r), WALL, np.float32)
    for k in range(n):
        hr[k, :, : 7 * r + 1 + k] = 1000.0  # the edge inside the 8th low-res column
    return tof_footprint(hr, r)
