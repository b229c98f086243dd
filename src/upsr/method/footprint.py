"""Whether a depth sensor integrates a footprint (time of flight) or samples points.

Beyond the paper. A time-of-flight pixel returns the mean depth of its footprint, so where
the footprint straddles a depth edge it returns a mix of the two surfaces
(:mod:`upsr.method.mixed` removes those); a point-sampling sensor (structured light, stereo,
renders) gives a depth between two surfaces only on steep slopes, which the mixed-pixel test
would take for mixes. :func:`footprint_share` tells them apart from the video itself (how
often an edge between two flat surfaces has a pixel between them, against how often a
footprint would give one), :func:`has_mixed_pixels` decides (``remove_mixed="auto"``, once per
video; the recursive mode pools its first frames as they arrive, :func:`footprint_counts`).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

__all__ = [
    "FLAT_END_SHARE",
    "MIXED_SHARE",
    "MIXED_SHARE_HYSTERESIS",
    "footprint_counts",
    "footprint_share",
    "has_mixed_pixels",
]

#: :func:`footprint_share` from which a video's sensor is taken to mix depths at edges (ToF)
#: and its mixed pixels are removed (``remove_mixed="auto"``). On the realistic scenes (seeds
#: 0–7 at 64×56, 0–3 at 128×112, edge_mm = max(100, 4σ)), pooled over the first 9 frames:
#: 0.47 and 0.58–2.8 with ToF footprints at σ = 10–30 mm, 0–0.41 with point samples at
#: σ = 0–30 mm; over the first frame alone, which the recursive mode must decide from, 9 of
#: the 384 cases fall on the wrong side (16 with every pixel weighing alike, at 0.55).
MIXED_SHARE = 0.5
#: A decision taken from the frames so far (the recursive mode pools its first N frames as
#: they arrive) turns the removal off again only below MIXED_SHARE minus this.
MIXED_SHARE_HYSTERESIS = 0.05
#: The ends of a run of :func:`footprint_share` are flat: each step beyond the edge (c to a,
#: b to e) at most this share of the step across it (a to b). A steep slope under strong
#: noise, whose steps are alike, does not pass for two flat surfaces.
FLAT_END_SHARE = 1.0 / 6.0


def footprint_share(frames: npt.ArrayLike, edge_mm: float) -> float:
    """How often a depth edge between two flat surfaces has a pixel between them, against how
    often a footprint sensor would give one.

    Over every run of five pixels along a row or column, c a v b e, whose ends are flat
    (``|c − a|`` and ``|e − b|`` at most ``edge_mm`` and at most :data:`FLAT_END_SHARE` of
    ``|b − a|``) across a large edge (``|b − a|`` more than 3·``edge_mm``): the number of those
    whose middle v lies more than ``edge_mm`` from both a and b, divided by the number a
    sensor that integrates each pixel's footprint (ToF) would give, an edge placed uniformly
    in the pixel mixing beyond ``edge_mm`` of both surfaces with probability
    1 − 2·``edge_mm``/|b − a|. About 1 for ToF; a point-sampling sensor (structured light,
    stereo, renders) gives such pixels only on steep slopes (:data:`MIXED_SHARE`: the
    measured ranges). Dividing by the expectation keeps a room of near surfaces (small steps,
    few mixes beyond the threshold) from passing for a point sampler.

    Parameters
    ----------
    frames : array_like (..., h, w)
        Depth (mm), 0 or NaN = no measurement.
    edge_mm : float
        Depth step that separates two surfaces.

    Returns
    -------
    float: the ratio (≥ 0); 0 without any such edge.
    """
    return _share_of(*footprint_counts(frames, edge_mm))


def _share_of(mixes: float, expected: float) -> float:
    """:func:`footprint_share` from :func:`footprint_counts` (summed over frames to pool them)."""
    return mixes / expected if expected > 0 else 0.0


def footprint_counts(frames: npt.ArrayLike, edge_mm: float) -> tuple[float, float]:
    """The edges with a pixel between the surfaces and the number a footprint sensor would
    give, whose ratio is :func:`footprint_share` (sums over frames pool their evidence).

    Each run of such edge pixels along one edge (consecutive across the runs of five)
    weighs √(its length) in all: a straight edge's pixels share one sub-pixel offset, so
    its footprints mix all or none, and a box side one pixel wide seen edge-on by a point
    sampler is between its surfaces all along; counted pixel by pixel, one such edge
    decided a frame (a camera approaching boxes, seed 1: 31 of its 53 expected mixes)."""
    z = np.asarray(frames, np.float32)
    z = np.where(np.isnan(z), np.float32(0.0), z).reshape(-1, *z.shape[-2:])
    edge = float(edge_mm)
    expected = 0.0
    between = 0.0
    for axis in (1, 2):
        n = z.shape[axis]
        if n < 5:
            continue
        c, a, v, b, e = (np.take(z, range(o, n - 4 + o), axis=axis) for o in range(5))
        # the pixels beyond the run's ends (0 past the frame's border)
        pad = [(0, 0)] * 3
        pad[axis] = (1, 1)
        zp = np.pad(z, pad)
        before, after = (np.take(zp, range(o, n - 4 + o), axis=axis) for o in (0, 6))
        with np.errstate(invalid="ignore", divide="ignore"):
            ok = (c > 0) & (a > 0) & (v > 0) & (b > 0) & (e > 0)
            step = np.abs(b - a)
            outer = np.maximum(np.abs(c - a), np.abs(e - b))
            ok &= (step > 3 * edge) & (outer <= edge) & (outer <= FLAT_END_SHARE * step)
            # an end is no band of two pixels on the other surface: a thin part 1–2 px wide
            # seen by a footprint sensor is a band of mixes itself, with no mix beside it
            ok &= ~((before > 0) & (np.abs(before - b) <= edge))
            ok &= ~((after > 0) & (np.abs(after - a) <= edge))
            mid = ok & (v - np.minimum(a, b) > edge) & (np.maximum(a, b) - v > edge)
            # a footprint across the edge at a uniform place mixes farther than edge_mm
            # from both surfaces with probability 1 − 2·edge_mm / step
            chance = 1.0 - 2.0 * edge / step
        # runs along the edge: the last axis for a profile down a column, else the rows
        ok, mid, chance = (np.swapaxes(x, 1, 2) if axis == 2 else x for x in (ok, mid, chance))
        ok = ok.reshape(-1, ok.shape[-1])
        starts = ok & ~np.pad(ok[:, :-1], ((0, 0), (1, 0)))
        run = (np.cumsum(starts) - 1).reshape(ok.shape)[ok]
        length = np.sqrt(np.bincount(run))
        sel = ok.reshape(mid.shape)
        between += float(np.sum(np.bincount(run, mid[sel].astype(np.float64)) / length))
        expected += float(np.sum(np.bincount(run, chance[sel].astype(np.float64)) / length))
    return between, expected


def has_mixed_pixels(share: float, *, was: bool = False) -> bool:
    """Whether a video's :func:`footprint_share` says its sensor mixes depths at edges (ToF):
    at least :data:`MIXED_SHARE`, or, ``was`` it said so before (a share pooled over the
    frames so far), at least :data:`MIXED_SHARE` − :data:`MIXED_SHARE_HYSTERESIS`."""
    return share >= MIXED_SHARE - (MIXED_SHARE_HYSTERESIS if was else 0.0)
