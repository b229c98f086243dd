"""Clusters of like mixes: parts one to two time-of-flight pixels wide.

Beyond the paper. A time-of-flight pixel integrates its footprint
(:mod:`upsr.method.mixed`). A part one to two pixels wide (a leg of an animal seen by a
sensor of 60×80 pixels or more) that covers the same share of a few pixels side by side
returns a small cluster of like mixes: 2318 / 2342 / 2340 / 2331 mm where a leg at 2120 mm
covers three quarters of two columns of pixels in front of a wall at 3000 mm. The mixed-pixel
test (:func:`upsr.method.mixed.remove_mixed_pixels`) takes them for a surface of their own,
since each has neighbours within the edge threshold, and the thin-part test
(:mod:`upsr.method.thin`) looks for parts narrower than a pixel; upsampled, the cluster is a
block of flying pixels.

:func:`mixed_clusters` finds them: a set of kept pixels linked through 8-neighbours within
the edge threshold (one surface) that is small (at most :data:`CLUSTER_PX` pixels, within
:data:`CLUSTER_SPAN_PX` × :data:`CLUSTER_SPAN_PX`), lies in front of some kept neighbour and
behind another by more than the edge threshold (between two surfaces, like a mixed pixel),
touches no border of the image (a surface that runs off the image is not known to be small)
and has no steep slope through it: no pixel of it whose neighbours on both sides step through
it evenly, or whose next two steps in one direction leave it by more than the edge threshold
and agree (:data:`upsr.method.slopes.STEEP_RUN_RATIO`; a floor seen at a grazing angle, one
row of pixels per step, is a surface). Its pixels are then mixed: they abstain in the fusion
and :func:`upsr.method.mixed.split_mixed_pixels` splits their blocks between the surfaces
around them.

A part that fills its pixels across (a leg two pixels wide on the pixel grid) gives such a
cluster too, at its true depth; the rule splits it between the surfaces around it (what that
costs: the constants below, the README's depth rules and docs/notes/depth-rules.md).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from upsr.method.slopes import STEEP_RUN_RATIO, _steps_agree

__all__ = ["CLUSTER_PX", "CLUSTER_SPAN_PX", "mixed_clusters"]

#: Most pixels of a cluster of like mixes (:func:`mixed_clusters`). Realistic galloping animal,
#: ToF σ = 10 mm, seed 0 (``benchmarks/realistic_eval.py --quick --no-oracle --tof-shape H W``):
#: flying pixels at 60×80 1.67 → 0.88 %, at 112×128 1.76 → 1.39 %, at 120×160 2.65 → 2.12 %
#: (windowed), its rmse +1–2 % (with 6 pixels). 9 (every cluster within the span, 6 Dec 2026):
#: the same outputs on all scenes and sensors of seeds 0–7 (``--seed S``, also with
#: ``--tof-sigma 20 --tof-dropout 0.01``); on the animal half
#: a pixel off the pixel grid (``--scenes gallop room --frames 10 --seed S``, S = 0–3) its ToF
#: flying pixels 0.98 / 1.16 → 0.81 / 0.85 % windowed, 0.95 / 1.19 → 0.72 / 0.79 % recursive
#: on seeds 0 / 3 (seeds 1–2 and the room unchanged), rmse +0.2 … +1.5 %, edge accuracy −0.04
#: … +0.21 points; at 120×160 (``--tof-shape 120 160 --scenes gallop room``, seeds 0–1) 2.12 /
#: 1.90 → 1.88 / 1.61 % on seed 0, rmse +0.5 / +0.9 %, seed 1 unchanged. A leg 1.5 pixels
#: wide half a pixel off the grid returns two columns of like mixes, which with the mixes of
#: the neighbouring leg beside them make 7–9 pixels.
CLUSTER_PX = 9
#: ... and the most rows and columns it spans. Without this bound (and the border rule) legs
#: that fill one column of pixels four to six rows long were split too: the animal's rmse at
#: 64×56 +0.4 … +3.0 % on seeds 0–7 (+0.0 … +1.0 % with it); 2 kept only 1.67 → 1.58 % at 60×80.
CLUSTER_SPAN_PX = 3


@nb.njit(cache=True, nogil=True, inline="always")
def _inside(h, w, a, b):  # pragma: no cover - numba
    return 0 <= a < h and 0 <= b < w


@nb.njit(cache=True, nogil=True)
def _through_a_slope(z, kept, qi, qj, n, edge):  # pragma: no cover - numba
    """Whether a steep slope runs through the cluster's pixels (qi[:n], qj[:n]): along a row,
    column or diagonal a pixel's two kept neighbours step through it evenly (one step beyond
    the edge threshold), or its next two kept pixels in one direction step on evenly, the
    first beyond the edge threshold."""
    h, w = z.shape
    for q in range(n):
        i, j = qi[q], qj[q]
        v = z[i, j]
        for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1)):
            for sg in (-1, 1):
                a1, b1 = i + sg * di, j + sg * dj
                a2, b2 = i + 2 * sg * di, j + 2 * sg * dj
                if not (_inside(h, w, a2, b2) and kept[a1, b1] and kept[a2, b2]):
                    continue
                s1 = z[a1, b1] - v
                if abs(s1) > edge and _steps_agree(s1, z[a2, b2] - z[a1, b1], STEEP_RUN_RATIO):
                    return True
            ia, ja, ib, jb = i - di, j - dj, i + di, j + dj
            if not (_inside(h, w, ia, ja) and _inside(h, w, ib, jb)):
                continue
            if not (kept[ia, ja] and kept[ib, jb]):
                continue
            s1, s2 = v - z[ia, ja], z[ib, jb] - v
            if max(abs(s1), abs(s2)) > edge and _steps_agree(s1, s2, STEEP_RUN_RATIO):
                return True
    return False


@nb.njit(cache=True, nogil=True)
def _clusters_kernel(z, kept, edge, size, span, out):  # pragma: no cover - numba
    h, w = z.shape
    seen = np.zeros((h, w), np.bool_)
    qi = np.empty(h * w, np.int64)
    qj = np.empty(h * w, np.int64)
    for i0 in range(h):
        for j0 in range(w):
            if not kept[i0, j0] or seen[i0, j0]:
                continue
            # the pixels of (i0, j0)'s surface, breadth first; whether some kept neighbour
            # lies nearer / farther than the edge threshold
            seen[i0, j0] = True
            qi[0], qj[0] = i0, j0
            n, head = 1, 0
            nearer = farther = False
            while head < n:
                i, j = qi[head], qj[head]
                head += 1
                for a in range(max(i - 1, 0), min(i + 2, h)):
                    for b in range(max(j - 1, 0), min(j + 2, w)):
                        if not kept[a, b]:
                            continue
                        d = z[a, b] - z[i, j]
                        if abs(d) <= edge:
                            if not seen[a, b]:
                                seen[a, b] = True
                                qi[n], qj[n] = a, b
                                n += 1
                        elif d < 0:
                            nearer = True
                        else:
                            farther = True
            if n > size or not (nearer and farther):
                continue
            i_lo, i_hi = qi[:n].min(), qi[:n].max()
            j_lo, j_hi = qj[:n].min(), qj[:n].max()
            if i_hi - i_lo >= span or j_hi - j_lo >= span:
                continue
            if i_lo == 0 or j_lo == 0 or i_hi == h - 1 or j_hi == w - 1:
                continue
            if _through_a_slope(z, kept, qi, qj, n, edge):
                continue
            for q in range(n):
                out[qi[q], qj[q]] = True


def mixed_clusters(
    frame: np.ndarray,
    kept: np.ndarray,
    edge_mm: float,
    *,
    max_px: int = CLUSTER_PX,
    span_px: int = CLUSTER_SPAN_PX,
) -> np.ndarray:
    """The small clusters of like mixes among the ``kept`` pixels of one ToF frame.

    Parameters
    ----------
    frame : ndarray float32 (h, w)
        Depth (mm), 0 = no measurement.
    kept : ndarray bool (h, w)
        The pixels not yet found mixed (the links and the neighbours nearer or farther are
        read among these only).
    edge_mm : float
        Depth step that separates two surfaces.
    max_px, span_px : int
        :data:`CLUSTER_PX`, :data:`CLUSTER_SPAN_PX`.

    Returns
    -------
    ndarray bool (h, w): the pixels of the clusters (a subset of ``kept``).
    """
    z = np.ascontiguousarray(frame, np.float32)
    keep = np.ascontiguousarray(kept & (z > 0), np.bool_)
    out = np.zeros(z.shape, np.bool_)
    _clusters_kernel(z, keep, float(edge_mm), int(max_px), int(span_px), out)
    return out
