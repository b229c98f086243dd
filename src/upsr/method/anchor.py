"""The reference frame's own depth per low-res pixel, robustly, and the tolerance of the trust
test around it (beyond the paper; :mod:`upsr.method.trust` uses them).

:func:`reference_anchor`: per reference pixel, an edge-aware robust estimate of its own depth
(the median of its 3×3 neighbours on its surface) and the tolerance τ = k·σ + the local relief
of that surface, against which each registered sample is trusted or not.
"""

from __future__ import annotations

import numba as nb
import numpy as np
import numpy.typing as npt

from upsr.method.noise import _sigma_at
from upsr.method.slopes import STEEP_RUN_RATIO, _steps_agree
from upsr.method.sorting import _small_median

__all__ = [
    "OUTLIER_MAX_SIGMAS",
    "OWN_SURFACE",
    "OWN_SURFACE_SIGMAS",
    "TOLERANCE_FLOOR_MM",
    "noise_outliers",
    "reference_anchor",
    "steep_runs",
]

#: Smallest trust tolerance (mm): noiseless or coarsely quantised data still trust their own
#: surface's samples.
TOLERANCE_FLOOR_MM = 2.0
#: How far (noise σ at its depth) a pixel's anchor may lie from its own measurement before a
#: neighbour on the measurement's side makes it the median of the pixel's own surface
#: (:func:`reference_anchor` ``own_surface``). Realistic scenes, seeds 0–2
#: (``benchmarks/realistic_eval.py --quick --no-oracle --seed S``), recursive mode
#: (``"always"``): rmse geomean −0.4 … −0.7 %, surface rmse geomean −3.7 … −5.2 % (rooms and the
#: approaching camera's slopes down to −27 %; at worst the galloping animal at Laplace σ = 30,
#: +3 … +9 %). In the windowed mode, ``"always"`` cost the synthetic wall's r = 2 rmse 3.3 /
#: 2.5 % at σ = 0 / 10 (``benchmarks/synthetic_eval.py``: the rims of its point-sampled
#: blob), hence ``"except_rims"`` there (see :func:`reference_anchor`).
OWN_SURFACE_SIGMAS = 3.0
#: The values of :func:`reference_anchor`'s ``own_surface``, in the kernel's code order.
OWN_SURFACE = ("never", "always", "except_rims")


@nb.njit(cache=True, nogil=True, inline="always")
def _median9(p0, p1, p2, p3, p4, p5, p6, p7, p8):  # pragma: no cover - numba
    """The median of nine values: Devillard's network of 19 compare-exchanges on scalars
    (registers, no buffer; the median lands in p4)."""
    p1, p2 = min(p1, p2), max(p1, p2)
    p4, p5 = min(p4, p5), max(p4, p5)
    p7, p8 = min(p7, p8), max(p7, p8)
    p0, p1 = min(p0, p1), max(p0, p1)
    p3, p4 = min(p3, p4), max(p3, p4)
    p6, p7 = min(p6, p7), max(p6, p7)
    p1, p2 = min(p1, p2), max(p1, p2)
    p4, p5 = min(p4, p5), max(p4, p5)
    p7, p8 = min(p7, p8), max(p7, p8)
    p0, p3 = min(p0, p3), max(p0, p3)
    p5, p8 = min(p5, p8), max(p5, p8)
    p4, p7 = min(p4, p7), max(p4, p7)
    p3, p6 = min(p3, p6), max(p3, p6)
    p1, p4 = min(p1, p4), max(p1, p4)
    p2, p5 = min(p2, p5), max(p2, p5)
    p4, p7 = min(p4, p7), max(p4, p7)
    p4, p2 = min(p4, p2), max(p4, p2)
    p6, p4 = min(p6, p4), max(p6, p4)
    p4, p2 = min(p4, p2), max(p4, p2)
    return p4


@nb.njit(cache=True, nogil=True, inline="always")
def _near(u, v, edge):  # pragma: no cover - numba
    """Whether ``u`` has depth and lies within ``edge`` of ``v`` (without a branch)."""
    return (u > 0) & (abs(u - v) <= edge)


@nb.njit(cache=True, nogil=True, inline="always")
def _shifted_rows(z, i):  # pragma: no cover - numba
    """Rows i − 1, i and i + 1 of ``z``, each as three slices of w − 2 shifted by 0, 1 and 2
    columns: element j of the nine is the 3×3 neighbourhood of (i, j + 1) in row-major order,
    read in a loop over j without index arithmetic (SIMD)."""
    n = z.shape[1] - 2
    return (
        z[i - 1, 0:n], z[i - 1, 1 : n + 1], z[i - 1, 2 : n + 2],
        z[i, 0:n], z[i, 1 : n + 1], z[i, 2 : n + 2],
        z[i + 1, 0:n], z[i + 1, 1 : n + 1], z[i + 1, 2 : n + 2],
    )  # fmt: skip


@nb.njit(cache=True, nogil=True, inline="always")
def _nine(rows, j):  # pragma: no cover - numba
    """The nine samples around (i, j + 1) from :func:`_shifted_rows`, row-major."""
    return (
        rows[0][j], rows[1][j], rows[2][j], rows[3][j], rows[4][j], rows[5][j],
        rows[6][j], rows[7][j], rows[8][j],
    )  # fmt: skip


@nb.njit(cache=True, nogil=True, inline="always")
def _interior_medians(z, i, edge, out):  # pragma: no cover - numba
    """out[j] (0 < j < w − 1): the anchor of interior pixel (i, j) whose 8 neighbours all
    lie within ``edge`` of it and of their median (the common case; both steps of the
    general rule give that median), or 0 where that does not hold. Branch-free over the
    row, whose loop reads only shifted row slices (SIMD)."""
    rows = _shifted_rows(z, i)
    o = out[1 : z.shape[1] - 1]
    for j in range(o.size):
        p0, p1, p2, p3, v, p5, p6, p7, p8 = _nine(rows, j)
        ok = (
            _near(p0, v, edge) & _near(p1, v, edge) & _near(p2, v, edge)
            & _near(p3, v, edge) & _near(v, v, edge) & _near(p5, v, edge)
            & _near(p6, v, edge) & _near(p7, v, edge) & _near(p8, v, edge)
        )  # fmt: skip
        c = _median9(p0, p1, p2, p3, v, p5, p6, p7, p8)
        ok &= (
            (abs(p0 - c) <= edge) & (abs(p1 - c) <= edge) & (abs(p2 - c) <= edge)
            & (abs(p3 - c) <= edge) & (abs(v - c) <= edge) & (abs(p5 - c) <= edge)
            & (abs(p6 - c) <= edge) & (abs(p7 - c) <= edge) & (abs(p8 - c) <= edge)
        )  # fmt: skip
        o[j] = c if ok else np.float32(0.0)


@nb.njit(cache=True, nogil=True, inline="always")
def _own_surface(z, i, j, c, sigma, power, edge, buf, mode):  # pragma: no cover - numba
    """The anchor c of pixel (i, j), or, where it lies beyond OWN_SURFACE_SIGMAS·σ of the
    pixel's own measurement v and a neighbour within that of v lies beyond it of c (v is on a
    surface of its own, not a noise outlier: a wall meeting a slope inside the pixel's
    block), the median of v and its neighbours within OWN_SURFACE_SIGMAS·σ of it. ``mode``:
    the index in OWN_SURFACE (0: c; 2: c also where c is nearer than v and a neighbour lies
    beyond ``edge`` of v, the rim of a nearer surface)."""
    if mode == 0:
        return c
    v = z[i, j]
    sig = _sigma_at(sigma, power, v)
    lim = OWN_SURFACE_SIGMAS * sig
    if not abs(c - v) > lim:
        return c
    if mode == 2 and c < v and _beside_an_edge(z, i, j, edge):
        return c
    m = _within(z, i, j, v, lim, buf)
    beyond = 0  # (v itself is one of them)
    for q in range(m):
        beyond += 1 if abs(buf[q] - c) > lim else 0
    return _small_median(buf, m) if beyond >= 2 else c


@nb.njit(cache=True, nogil=True, inline="always")
def _beside_an_edge(z, i, j, edge):  # pragma: no cover - numba
    """Whether a valid 3×3 neighbour of (i, j) lies beyond ``edge`` of it."""
    h, w = z.shape
    v = z[i, j]
    for a in range(max(i - 1, 0), min(i + 2, h)):
        for b in range(max(j - 1, 0), min(j + 2, w)):
            u = z[a, b]
            if u > 0 and abs(u - v) > edge:
                return True
    return False


@nb.njit(cache=True, nogil=True, inline="always")
def _within(z, i, j, centre, limit, buf):  # pragma: no cover - numba
    """The valid 3×3 neighbours of (i, j), itself included, within ``limit`` of ``centre``:
    copied to buf[:m]; returns m."""
    h, w = z.shape
    m = 0
    for a in range(max(i - 1, 0), min(i + 2, h)):
        for b in range(max(j - 1, 0), min(j + 2, w)):
            u = z[a, b]
            if u > 0 and abs(u - centre) <= limit:
                buf[m] = u
                m += 1
    return m


@nb.njit(cache=True, nogil=True, inline="always")
def _shared(anchor, i, j, a0, edge):  # pragma: no cover - numba
    """Whether an 8-neighbour of (i, j) has an anchor within ``edge`` of ``a0``."""
    h, w = anchor.shape
    for a in range(max(i - 1, 0), min(i + 2, h)):
        for b in range(max(j - 1, 0), min(j + 2, w)):
            u = anchor[a, b]
            if (a != i or b != j) and u > 0 and abs(u - a0) <= edge:
                return True
    return False


@nb.njit(cache=True, nogil=True, parallel=True)
def _anchor_kernel(
    z, steep, edge, sigma, power, k, floor, own_surface, anchor, tol
):  # pragma: no cover - numba
    h, w = z.shape
    for i in nb.prange(h):
        buf = np.empty(9, np.float32)
        medians = np.zeros(w, np.float32)
        if 0 < i < h - 1 and w > 2:
            _interior_medians(z, i, edge, medians)
        for j in range(w):
            v = z[i, j]
            anchor[i, j] = 0.0
            if not v > 0:
                continue
            if 0 < i < h - 1 and 0 < j < w - 1:
                c = np.float64(medians[j])
                if c > 0:
                    anchor[i, j] = _own_surface(z, i, j, c, sigma, power, edge, buf, own_surface)
                    continue
            # the median of the neighbours on the pixel's surface, then of those on the
            # surface of that median: a noise outlier at the pixel itself (its neighbours
            # within the edge threshold of it all on one side) does not pull the anchor along
            c = v
            for step in range(2):
                m = _within(z, i, j, c, edge, buf)
                if step == 0 and m == 1:
                    break  # no neighbour on its surface: a noise outlier, no anchor
                c = _small_median(buf, m)
            if m > 1:
                anchor[i, j] = _own_surface(z, i, j, c, sigma, power, edge, buf, own_surface)
            elif steep[i, j]:
                anchor[i, j] = v  # a steep surface one pixel wide: its own measurement
    # an anchor that no 8-neighbour's anchor shares is a noise outlier after all: one noisy
    # neighbour within the edge threshold of it, itself on the surface around (its anchor
    # far from this one), made the two a surface of their own
    shared = np.empty((h, w), np.bool_)
    for i in nb.prange(h):
        for j in range(w):
            a0 = anchor[i, j]
            shared[i, j] = not a0 > 0 or steep[i, j] or _shared(anchor, i, j, a0, edge)
    for i in nb.prange(h):
        for j in range(w):
            if not shared[i, j]:
                anchor[i, j] = 0.0
    for i in nb.prange(h):
        for j in range(w):
            a0 = anchor[i, j]
            tol[i, j] = 0.0
            if not a0 > 0:
                continue
            relief = 0.0
            for di, dj in ((-1, 0), (1, 0), (0, -1), (0, 1)):
                a = i + di
                b = j + dj
                if 0 <= a < h and 0 <= b < w:
                    u = anchor[a, b]
                    if u > 0 and abs(u - a0) <= edge:
                        relief = max(relief, abs(u - a0))
            sig = _sigma_at(sigma, power, a0)
            tol[i, j] = max(k * sig + relief, floor)


#: :func:`noise_outliers`: a sample this many σ or less from the median around it may be a
#: noise outlier (Laplacian noise: a sample beyond 8 σ once in 10⁵); a small surface farther
#: off is taken for what it is.
OUTLIER_MAX_SIGMAS = 8.0


@nb.njit(cache=True, nogil=True)
def _members(z, i, j, v, c):  # pragma: no cover - numba
    """(count, last) of the valid 8-neighbours of (i, j) nearer to ``v`` than to ``c``."""
    h, w = z.shape
    n = 0
    last = -1
    for a in range(max(i - 1, 0), min(i + 2, h)):
        for b in range(max(j - 1, 0), min(j + 2, w)):
            u = z[a, b]
            if (a != i or b != j) and u > 0 and abs(u - v) < abs(u - c):
                n += 1
                last = a * w + b
    return n, last


@nb.njit(cache=True, nogil=True, inline="always")
def _outlier_medians(z, i, out):  # pragma: no cover - numba
    """out[j] (0 < j < w − 1): the median of the 3×3 samples around (i, j) where all 9 have
    depth and at most one of the 8 neighbours lies beyond the pixel's sample on either side
    (a candidate outlier of :func:`noise_outliers`), else 0. Branch-free over the row, whose
    loop reads only shifted row slices (SIMD)."""
    rows = _shifted_rows(z, i)
    o = out[1 : z.shape[1] - 1]
    for j in range(o.size):
        p0, p1, p2, p3, v, p5, p6, p7, p8 = _nine(rows, j)
        ok = (v > 0) & (p0 > 0) & (p1 > 0) & (p2 > 0) & (p3 > 0)
        ok &= (p5 > 0) & (p6 > 0) & (p7 > 0) & (p8 > 0)
        above = (
            np.int32(p0 > v) + np.int32(p1 > v) + np.int32(p2 > v) + np.int32(p3 > v)
            + np.int32(p5 > v) + np.int32(p6 > v) + np.int32(p7 > v) + np.int32(p8 > v)
        )  # fmt: skip
        below = (
            np.int32(p0 < v) + np.int32(p1 < v) + np.int32(p2 < v) + np.int32(p3 < v)
            + np.int32(p5 < v) + np.int32(p6 < v) + np.int32(p7 < v) + np.int32(p8 < v)
        )  # fmt: skip
        ok &= min(above, below) <= 1
        c = _median9(p0, p1, p2, p3, v, p5, p6, p7, p8)
        o[j] = c if ok else np.float32(0.0)


@nb.njit(cache=True, nogil=True, inline="always")
def _off_median(u, c):  # pragma: no cover - numba
    """|u − c| (float64 c, rounded to float32 as a buffer of samples holds it)."""
    return np.float32(abs(u - c))


@nb.njit(cache=True, nogil=True, parallel=True)
def _outlier_kernel(z, sigma, power, around, limit):  # pragma: no cover - numba
    h, w = z.shape
    for i in nb.prange(h):
        medians = np.zeros(w, np.float32)
        if 0 < i < h - 1 and w > 2:
            _outlier_medians(z, i, medians)
        for j in range(w):
            around[i, j] = 0.0
            limit[i, j] = 0.0
            # (beside a hole or the border a slope's median is one-sided; and a neighbour
            # beyond v, away from the median, is nearer to v: an outlier has at most one)
            if not medians[j] > 0:
                continue
            v = z[i, j]
            p0, p1, p2 = z[i - 1, j - 1], z[i - 1, j], z[i - 1, j + 1]
            p3, p5 = z[i, j - 1], z[i, j + 1]
            p6, p7, p8 = z[i + 1, j - 1], z[i + 1, j], z[i + 1, j + 1]
            c = np.float64(medians[j])
            sig = _sigma_at(sigma, power, c)
            if not abs(v - c) > OWN_SURFACE_SIGMAS * sig:
                continue
            # the spread of the samples around the median (a slope's relief, the noise)
            spread = np.float64(
                _median9(
                    _off_median(p0, c), _off_median(p1, c), _off_median(p2, c),
                    _off_median(p3, c), _off_median(v, c), _off_median(p5, c),
                    _off_median(p6, c), _off_median(p7, c), _off_median(p8, c),
                )
            )  # fmt: skip
            dev = abs(v - c) - spread
            if not (OWN_SURFACE_SIGMAS * sig < dev <= OUTLIER_MAX_SIGMAS * sig):
                continue
            # a surface of at most two pixels: v alone, or with one neighbour (nearer to v
            # than to the median around) that has no other (a thin part has neighbours along
            # it; its tip one that has two)
            n, last = _members(z, i, j, v, c)
            if n == 1:
                n = _members(z, last // w, last % w, v, c)[0]
            if n <= 1:
                around[i, j] = c
                limit[i, j] = OWN_SURFACE_SIGMAS * sig + spread


def noise_outliers(
    z: npt.ArrayLike, sigma_mm: float, *, noise_profile: tuple[float, float] | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Samples that may be noise outliers, and the surface around them.

    An outlier lies off the median c of its 3×3 neighbours (all measured) by more than
    :data:`OWN_SURFACE_SIGMAS`·σ and at most :data:`OUTLIER_MAX_SIGMAS`·σ beyond the spread of
    those neighbours around c (the median of their distances to it: a slope's relief, the
    noise), on a surface of at most two pixels (no 8-neighbour nearer to it than to c, or one,
    which has no other). A pair of noise outliers beside each other (Laplacian σ = 30 mm: two
    samples 3–5 σ off the same side, a few times per frame of a 64×56 sensor) has an anchor
    of its own (:func:`reference_anchor`), as a thin part has; but a thin part has neighbours
    along it. The recursive mode lets a state on the surface around outvote such samples, as
    the windowed mode's other frames do. Without noise (σ = 0) nothing is an outlier.

    Parameters
    ----------
    z : array_like (h, w)
        A low-res frame (mm, 0: no measurement).
    sigma_mm : float
        Noise std (mm).
    noise_profile : (float, float), optional
        (σ₁, p): σ(c) = σ₁·(c / 1 m)^p at each median c instead of ``sigma_mm`` (p > 0).

    Returns
    -------
    around : ndarray float32 (h, w)
        c at the outliers, 0 elsewhere.
    limit : ndarray float32 (h, w)
        :data:`OWN_SURFACE_SIGMAS`·σ + the spread at the outliers (how far from c a depth
        still lies on the surface around), 0 elsewhere.
    """
    a = np.ascontiguousarray(z, np.float32)
    around = np.empty(a.shape, np.float32)
    limit = np.empty(a.shape, np.float32)
    sigma, power = _sigma_and_power(sigma_mm, noise_profile)
    _outlier_kernel(a, sigma, power, around, limit)
    return around, limit


def steep_runs(z: npt.ArrayLike, edge_mm: float) -> np.ndarray:
    """Pixels on a steep run: along a row, column or diagonal, three consecutive steps
    beyond ``edge_mm`` through the pixel or ending at it agree (same sign, within
    :data:`upsr.method.slopes.STEEP_RUN_RATIO`). A surface one pixel wide seen at a grazing
    angle (a box side edge-on beside a wall: the room of seed 6 at Laplace σ = 0, steps of
    130–160 mm per pixel down a column), none of whose pixels lies within the edge
    threshold of another, is one; a noise outlier (a step out and one back) and a mixed
    pixel between two flat surfaces (one step across the edge) are not.

    Parameters
    ----------
    z : array_like (h, w)
        Depth (mm), 0 or NaN = no measurement.
    edge_mm : float
        Depth step that separates two surfaces.

    Returns
    -------
    ndarray bool (h, w)
    """
    z = np.ascontiguousarray(z, np.float32)
    z = np.where(np.isnan(z), np.float32(0.0), z)
    out = np.empty(z.shape, np.bool_)
    _steep_kernel(z, np.float32(edge_mm), np.float32(STEEP_RUN_RATIO), out)
    return out


@nb.njit(cache=True, nogil=True, inline="always")
def _run_step(z, i, j, di, dj, k, edge):  # pragma: no cover - numba
    """The step from pixel k to pixel k + 1 along (di, dj) from (i, j) where both have depth
    and it exceeds ``edge``, else 0."""
    h, w = z.shape
    a0, b0, a1, b1 = i + k * di, j + k * dj, i + (k + 1) * di, j + (k + 1) * dj
    if not (0 <= a0 < h and 0 <= b0 < w and 0 <= a1 < h and 0 <= b1 < w):
        return np.float32(0.0)
    u, v = z[a0, b0], z[a1, b1]
    if not (u > 0 and v > 0) or abs(v - u) <= edge:
        return np.float32(0.0)
    return v - u


@nb.njit(cache=True, nogil=True, parallel=True)
def _steep_kernel(z, edge, ratio, out):  # pragma: no cover - numba
    h, w = z.shape
    for i in nb.prange(h):
        steps = np.empty(6, np.float32)
        for j in range(w):
            out[i, j] = False
            v = z[i, j]
            if not v > 0:
                continue
            if 0 < i < h - 1 and 0 < j < w - 1:
                # (the common case: no step beyond the edge threshold to any neighbour)
                beyond = False
                for a in range(i - 1, i + 2):
                    for b in range(j - 1, j + 2):
                        u = z[a, b]
                        beyond |= u > 0 and abs(u - v) > edge
                if not beyond:
                    continue
            for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1)):
                # (a run of three steps through the pixel takes one of its own two)
                if (
                    _run_step(z, i, j, di, dj, -1, edge) == 0
                    and _run_step(z, i, j, di, dj, 0, edge) == 0
                ):
                    continue
                for k in range(6):
                    steps[k] = _run_step(z, i, j, di, dj, k - 3, edge)
                run = 0  # consecutive agreeing pairs of steps
                for k in range(5):
                    if _steps_agree(steps[k], steps[k + 1], ratio):
                        run += 1
                        if run >= 2:  # three steps: pixels -3..0, -2..1, -1..2 or 0..3
                            out[i, j] = True
                            break
                    else:
                        run = 0
                if out[i, j]:
                    break


def _sigma_and_power(
    sigma_mm: float, noise_profile: tuple[float, float] | None
) -> tuple[float, float]:
    """(σ, 0) of one noise std, or (σ₁, p) of a profile whose power is not 0 (kernels'
    arguments: σ(z) = σ₁·(z / 1 m)^p)."""
    if noise_profile is not None and noise_profile[1] > 0:
        return float(noise_profile[0]), float(noise_profile[1])
    return float(sigma_mm), 0.0


def reference_anchor(
    reference: npt.ArrayLike,
    sigma_mm: float,
    k: float,
    edge_mm: float,
    *,
    noise_profile: tuple[float, float] | None = None,
    own_surface: str = "never",
    keep_steep: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """The reference's own depth, robustly, and how far a trusted sample may lie from it.

    Parameters
    ----------
    reference : array_like (h, w)
        The reference low-res frame (mm, 0 = no measurement).
    sigma_mm : float
        Noise std of the video (mm).
    noise_profile : (float, float), optional
        (σ₁, p) of :func:`upsr.method.noise.noise_profile`: with p > 0 the σ of the tolerance
        is σ₁·(a / 1 m)^p at each pixel's anchor a instead of ``sigma_mm``.
    k : float
        Tolerance in units of the noise std.
    own_surface : {"never", "always", "except_rims"}
        Keep each anchor on its pixel's own surface (below): ``"always"`` in the recursive
        mode, which restarts a pixel from its anchor; ``"except_rims"`` in the windowed mode.
    edge_mm : float
        Depth step that separates two surfaces: only the neighbours within it of a pixel take
        part in its anchor and relief (never across a depth edge).
    keep_steep : bool
        A pixel on a steep run (:func:`steep_runs`) without a neighbour on its surface is
        anchored at its own measurement, not a lone outlier. Off where the sensor mixes
        (ToF: a line of mixes its removal left, along a slope, steps like one).

    Returns
    -------
    anchor : ndarray float32 (h, w)
        Median of the pixel's 3×3 neighbours (itself included) within ``edge_mm`` of the
        median of those within ``edge_mm`` of it (two steps: an outlier at the pixel does not
        choose its neighbours); 0 where the reference has no depth, where no 8-neighbour
        lies on its surface (a lone outlier, which the other frames then outvote; a thin
        part one pixel wide still has neighbours along it) unless it lies on a steep run
        (``keep_steep``: a surface one pixel wide seen at a grazing angle, whose anchor is
        its own measurement), and where no 8-neighbour's
        anchor lies within ``edge_mm`` of the pixel's (an outlier whose one neighbour within
        the edge threshold is a noisy pixel of the surface around: Samba, r = 2, Laplacian
        σ = 50 mm, a +5σ sample and a +2.7σ neighbour whose median rejected every other
        frame's samples of that block). With ``own_surface`` (not
        ``"never"``), where that median lies more than :data:`OWN_SURFACE_SIGMAS`·σ from the
        pixel's own measurement and a neighbour within that of the measurement lies beyond it
        of the median (the pixel on a surface of its own: a slope beginning inside its block
        beside a wall, whose pixels the median's second step took in), the median of the
        pixel and those neighbours; with ``"except_rims"`` not where the median is nearer
        than the measurement and a neighbour lies beyond ``edge_mm`` of it (the rim of a
        nearer surface, its steep far end point-sampled: the windowed fusion's block there
        is half the surface behind, which the measurement's anchor would outvote).
    tolerance : ndarray float32 (h, w)
        τ = k·σ (or k·σ(anchor)) + the largest difference to the anchor of a 4-neighbour on
        the same surface
        (the relief of a slanted surface over one low-res pixel), at least
        :data:`TOLERANCE_FLOOR_MM`; 0 where the reference has no depth.
    """
    if own_surface not in OWN_SURFACE:
        raise ValueError(f"own_surface must be one of {OWN_SURFACE}, not {own_surface!r}")
    z = np.ascontiguousarray(reference, np.float32)
    z = np.where(np.isnan(z), np.float32(0.0), z)
    anchor = np.empty(z.shape, np.float32)
    tol = np.empty(z.shape, np.float32)
    sigma, power = _sigma_and_power(sigma_mm, noise_profile)
    floor = TOLERANCE_FLOOR_MM
    mode = OWN_SURFACE.index(own_surface)
    steep = steep_runs(z, edge_mm) if keep_steep else np.zeros(z.shape, np.bool_)
    _anchor_kernel(z, steep, float(edge_mm), sigma, power, float(k), floor, mode, anchor, tol)
    return anchor, tol
