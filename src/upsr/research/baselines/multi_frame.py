"""Multi-frame baselines of paper §7 with the motion of UP-SR: dynamic median Shift & Add
(Farsiu et al. 2004, "dynamic S&A" [41]) and LidarBoost (Schuon et al. 2009).

Both use the consecutive flows between *upsampled* frames that UP-SR estimates
(:func:`upsampled_flows`, paper §4, §5.2, the shared :class:`upsr.method.frontend.MotionFrontEnd`),
chained by composition (:mod:`upsr.method.registration`); precomputed flows may be passed instead.
Pixel geometry of ``SPEC.md`` §1; depth is float32 mm, 0 = unknown.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterator

import cv2
import numpy as np
import numpy.typing as npt
from scipy import ndimage, sparse

from upsr.errors import InputError
from upsr.method.config import UPSRConfig
from upsr.method.frontend import MotionFrontEnd
from upsr.method.registration import flows_to_reference
from upsr.method.upsampling import _check_scale
from upsr.research.baselines._common import _as_frames

__all__ = [
    "EnergyCallback",
    "FlowPair",
    "lidarboost",
    "shift_add",
    "upsampled_flows",
]


#: Consecutive flows of a video on the high-res grid: ``(forward, backward)``, each of shape
#: (T−1, r·h, r·w, 2); ``forward[t]`` maps frame t to t+1, ``backward[t]`` frame t+1 to t.
FlowPair = tuple[np.ndarray, np.ndarray]


# ------------------------------------------------------------------------------------------------
# The motion of UP-SR, shared by the multi-frame baselines
# ------------------------------------------------------------------------------------------------
def upsampled_flows(lowres: npt.ArrayLike, r: int, *, config: UPSRConfig | None = None) -> FlowPair:
    """Consecutive optical flows between the *upsampled* frames, as UP-SR estimates them.

    Paper §4 and §5.2, steps 1–3 of ``SPEC.md`` §2, by UP-SR's own motion front-end
    (:class:`upsr.method.frontend.MotionFrontEnd`, as in :class:`upsr.method.windowed.UPSR`)
    with the flow grid at the full r: each frame is densely upsampled (nearest, eq. 13–15),
    bilateral-prefiltered and mapped to 8 bit with one fixed depth range per video; the flow
    backend of ``config`` then runs between consecutive frames in both directions, and motion
    that the depth does not support is zeroed
    (:func:`upsr.method.motion.suppress_spurious_motion`, edge rule included). The depth range
    and the noise level are fixed from the first ``config.n_frames`` frames (the first
    window), unless ``config`` gives them.

    Parameters
    ----------
    lowres : array_like, shape (T, h, w) (or one (h, w) frame: no flow)
        Depth video (mm); 0 or NaN = invalid.
    r : int
        SR factor ≥ 1: the flows live on the (r·h, r·w) grid.
    config : UPSRConfig, optional
        Prefilter, flow backend, spurious-motion parameters and window length
        (``UPSRConfig(scale=r)`` by default; its ``scale`` is taken as r, ``flow_scale`` is
        ignored).

    Returns
    -------
    (forward, backward) : tuple of ndarray float32, each (T−1, r·h, r·w, 2)
        ``forward[t]`` is the flow from frame t to frame t+1, ``backward[t]`` from t+1 to t
        (``flow[i, j] = (dx, dy)``, see :mod:`upsr.method.motion`).
    """
    r = _check_scale(r)
    frames, _ = _as_frames(lowres)
    cfg = config if config is not None else UPSRConfig(scale=r)
    if cfg.scale != r:
        cfg = dataclasses.replace(cfg, scale=r, flow_scale=None)
    t, h, w = frames.shape
    fwd = np.zeros((max(t - 1, 0), h * r, w * r, 2), np.float32)
    bwd = np.zeros_like(fwd)
    if t < 2:
        return fwd, bwd
    front = MotionFrontEnd(cfg, w, grid_scale=r)
    front.fix_statistics(frames[: cfg.n_frames])
    pre = [front.prefilter(f) for f in frames]
    guides = [front.guide(p) for p in pre]
    for k in range(t - 1):
        fwd[k], bwd[k] = front.flow_pair(
            pre[k], pre[k + 1], guides[k], guides[k + 1], parallel=front.thread_safe
        )
    return fwd, bwd


def _check_n_frames(n_frames: int) -> int:
    if isinstance(n_frames, bool) or not isinstance(n_frames, (int, np.integer)) or n_frames < 1:
        raise InputError(f"n_frames must be an integer >= 1, got {n_frames!r}")
    return int(n_frames)


def _check_flows(flows: FlowPair, t: int, shape: tuple[int, int]) -> FlowPair:
    if not isinstance(flows, (tuple, list)) or len(flows) != 2:
        raise InputError("flows must be a pair (forward, backward) of flow arrays")
    fwd, bwd = (np.asarray(f, np.float32) for f in flows)
    want = (t - 1, *shape, 2)
    for name, f in (("forward", fwd), ("backward", bwd)):
        if f.shape != want:
            raise InputError(f"flows: {name} must have shape {want}, got {f.shape}")
        if not np.isfinite(f).all():
            raise InputError(f"flows: {name} contains NaN or ±inf")
    return fwd, bwd


def _windows(
    frames: np.ndarray,
    r: int,
    n_frames: int,
    flows: FlowPair | None,
    config: UPSRConfig | None,
) -> Iterator[tuple[np.ndarray, list[np.ndarray]]]:
    """For every reference frame: the low-res frames of its window and their flows to it.

    The window holds N = min(n_frames, T) frames with the reference in the middle, shifted
    inwards at the ends of the video (as in :func:`upsr.method.windowed.window_start`). The flow
    from frame t to the reference (on the high-res grid) is the composition of consecutive
    flows (:func:`upsr.method.registration.flows_to_reference`).
    """
    t_total, h, w = frames.shape
    shape = (h * r, w * r)
    n = min(n_frames, t_total)
    if flows is None:
        cfg = config if config is not None else UPSRConfig(scale=r, n_frames=n)
        fwd, bwd = upsampled_flows(frames, r, config=cfg)
    else:
        fwd, bwd = _check_flows(flows, t_total, shape)
    for t in range(t_total):
        s = min(max(t - (n - 1) // 2, 0), t_total - n)
        idx = range(s, s + n)
        maps = flows_to_reference(
            t - s,
            [bwd[k - 1] if k >= 1 else None for k in idx],
            [fwd[k] if k < t_total - 1 else None for k in idx],
            shape,
        )
        yield frames[s : s + n], maps


def _sample_positions(
    frame: np.ndarray, to_ref: np.ndarray, r: int
) -> tuple[np.ndarray, np.ndarray]:
    """Where every low-res sample of a frame lands on the reference's high-res grid.

    The sample (i, j) sits at the centre q = ((i + 0.5)·r − 0.5, (j + 0.5)·r − 0.5) of its
    pixel; it moves to q + F(q), F the frame → reference flow read bilinearly at q.
    Returns (y, x) float arrays of shape (h, w), in high-res px.
    """
    h, w = frame.shape
    cy = ((np.arange(h) + 0.5) * r - 0.5).astype(np.float32)
    cx = ((np.arange(w) + 0.5) * r - 0.5).astype(np.float32)
    mx, my = np.meshgrid(cx, cy)
    disp = cv2.remap(
        np.ascontiguousarray(to_ref, np.float32),
        mx,
        my,
        cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_REPLICATE,
    )
    return my + disp[..., 1], mx + disp[..., 0]


# ------------------------------------------------------------------------------------------------
# Dynamic Shift & Add (Farsiu et al. 2004)
# ------------------------------------------------------------------------------------------------
def _shift_add_frame(
    frames: np.ndarray, maps: list[np.ndarray], r: int, fill: bool
) -> tuple[np.ndarray, np.ndarray]:
    """Median S&A of one window: (image (H, W) float32, number of samples per pixel)."""
    _, h, w = frames.shape
    hh, ww = h * r, w * r
    pix_list, val_list = [], []
    for frame, to_ref in zip(frames, maps, strict=True):
        py, px = _sample_positions(frame, to_ref, r)
        iy = np.floor(py + 0.5).astype(np.intp)
        ix = np.floor(px + 0.5).astype(np.intp)
        inside = (iy >= 0) & (iy < hh) & (ix >= 0) & (ix < ww)
        pix_list.append((iy * ww + ix)[inside])
        val_list.append(frame[inside])
    pix = np.concatenate(pix_list)
    val = np.concatenate(val_list)
    n_all = np.bincount(pix, minlength=hh * ww)
    good = val > 0
    pv, vv = pix[good], val[good]
    n_valid = np.bincount(pv, minlength=hh * ww)
    order = np.lexsort((vv, pv))
    vv = vv[order]
    start = np.concatenate([[0], np.cumsum(n_valid)[:-1]])
    has = n_valid > 0
    lo = start[has] + (n_valid[has] - 1) // 2
    hi = start[has] + n_valid[has] // 2
    med = np.zeros(hh * ww, np.float32)
    med[has] = 0.5 * (vv[lo] + vv[hi])
    # a pixel shows depth if most of the samples placed on it measured something
    out = np.where(2 * n_valid > n_all, med, np.float32(0.0)).reshape(hh, ww)
    measured = (n_all > 0).reshape(hh, ww)
    if fill and measured.any() and not measured.all():
        iy, ix = ndimage.distance_transform_edt(
            ~measured, return_distances=False, return_indices=True
        )
        out = out[iy, ix]
    return out.astype(np.float32), n_all.reshape(hh, ww)


def shift_add(
    lowres: npt.ArrayLike,
    r: int,
    n_frames: int = 9,
    *,
    flows: FlowPair | None = None,
    fill: bool = True,
    config: UPSRConfig | None = None,
) -> np.ndarray:
    """Dynamic median Shift & Add (Farsiu, Robinson, Elad, Milanfar 2004, "dynamic S&A" [41]).

    Farsiu et al., "Fast and robust multiframe super resolution", IEEE TIP 13(10), 2004, §IV:
    under translational motion and a space-invariant blur, the maximum-likelihood estimate of
    the blurred high-res image under Laplacian noise is the pixel-wise median of the shifted
    zero-filled upsampled frames, Ẑ = med_t{S_t⁻¹ Dᵀ y_t} over the samples that fall on each
    pixel. Here, for dynamic scenes, the shift S_t is the per-pixel motion of UP-SR:

    1. every low-res sample y_t(i, j) of every frame of the window (N frames, reference in the
       middle) sits at its pixel centre q (``SPEC.md`` §1) and moves to q + F_t(q) on the
       reference's high-res grid, F_t the frame t → reference motion obtained by composing the
       consecutive flows between upsampled frames (:func:`upsampled_flows`);
    2. the sample is placed on the **one** high-res pixel nearest to that position (Dᵀ:
       zero-filling, *not* dense upsampling); samples landing outside the grid are dropped;
    3. each pixel takes the median of the valid samples placed on it (mean of the two middle
       ones for an even count, as in Farsiu et al.); a pixel whose samples are mostly invalid
       (0, no return) is 0.

    Pixels that receive no sample at all are left to the regulariser of the subsequent
    deblurring step in Farsiu et al. (their weight matrix Φ is zero there). With
    ``fill=True`` (default) they take instead the value of the nearest pixel that received
    samples (a nearest-neighbour interpolation of the scattered samples: it creates no new
    depth value and never extends depth into "no return" areas); ``fill=False`` leaves them 0.

    Parameters
    ----------
    lowres : array_like, shape (T, h, w) or (h, w)
        Depth video (mm); 0 or NaN = invalid.
    r : int
        SR factor ≥ 1.
    n_frames : int
        Window length N (clipped to T).
    flows : (forward, backward), optional
        Precomputed consecutive flows on the high-res grid, see :func:`upsampled_flows`
        (default: computed with it).
    fill : bool
        Fill the pixels without any sample (see above).
    config : UPSRConfig, optional
        Motion parameters used when ``flows`` is None.

    Returns
    -------
    ndarray of float32, shape (T, r·h, r·w) (or (r·h, r·w) for one frame); 0 = unknown.
    """
    r = _check_scale(r)
    n_frames = _check_n_frames(n_frames)
    frames, single = _as_frames(lowres)
    out = np.stack(
        [
            _shift_add_frame(win, maps, r, fill)[0]
            for win, maps in _windows(frames, r, n_frames, flows, config)
        ]
    )
    return out[0] if single else out


# ------------------------------------------------------------------------------------------------
# LidarBoost (Schuon et al. 2009)
# ------------------------------------------------------------------------------------------------
#: The 8-neighbourhood of the LidarBoost regulariser and the distances that weight it.
_N8 = ((0, 1), (1, 0), (1, 1), (1, -1), (0, -1), (-1, 0), (-1, -1), (-1, 1))

#: Energy callback of :func:`lidarboost`: (reference frame, iteration, energy).
EnergyCallback = Callable[[int, int, float], None]


class _LidarBoostProblem:
    """E(x) = ‖A x − y‖² + λ Σ_p sqrt(Σ_{o ∈ N8} ((x_p − x_{p+o}) / |o|)² + ε²) on a support."""

    def __init__(
        self,
        frames: np.ndarray,
        maps: list[np.ndarray],
        r: int,
        support: np.ndarray,
        lam: float,
        eps_mm: float,
    ) -> None:
        hh, ww = support.shape
        n = int(support.sum())
        index = np.full(hh * ww, -1, np.intp)
        index[support.ravel()] = np.arange(n)
        # data term: sample (t, i, j) compared with x read bilinearly at its motion-compensated
        # position (D M_t x, point sampling at the low-res pixel centre); W_t drops the invalid
        # samples and those falling outside the grid or outside the support
        rows, cols, wts, ys = [], [], [], []
        n_rows = 0
        for frame, to_ref in zip(frames, maps, strict=True):
            py, px = _sample_positions(frame, to_ref, r)
            ok = (frame > 0) & (py >= 0) & (py <= hh - 1) & (px >= 0) & (px <= ww - 1)
            py, px, val = py[ok].astype(np.float64), px[ok].astype(np.float64), frame[ok]
            y0 = np.floor(py).astype(np.intp)
            x0 = np.floor(px).astype(np.intp)
            fy, fx = py - y0, px - x0
            y1 = np.minimum(y0 + 1, hh - 1)
            x1 = np.minimum(x0 + 1, ww - 1)
            c = np.stack(
                [
                    index[y0 * ww + x0],
                    index[y0 * ww + x1],
                    index[y1 * ww + x0],
                    index[y1 * ww + x1],
                ],
                axis=1,
            )
            wt = np.stack([(1 - fy) * (1 - fx), (1 - fy) * fx, fy * (1 - fx), fy * fx], axis=1)
            wt[c < 0] = 0.0
            total = wt.sum(axis=1)
            keep = total > 1e-6
            c, wt, val = c[keep], wt[keep] / total[keep, None], val[keep]
            m = len(val)
            nz = wt > 0
            rows.append(np.repeat(np.arange(n_rows, n_rows + m), 4).reshape(m, 4)[nz])
            cols.append(c[nz])
            wts.append(wt[nz])
            ys.append(val.astype(np.float64))
            n_rows += m
        self.A = sparse.csr_matrix(
            (np.concatenate(wts), (np.concatenate(rows), np.concatenate(cols))), shape=(n_rows, n)
        )
        self.y = np.concatenate(ys) if ys else np.zeros(0)
        self.AtA = (self.A.T @ self.A).tocsr()
        self.Aty = self.A.T @ self.y
        # regulariser: one row (x_p − x_q)/|o| per pixel p of the support and neighbour q = p + o
        # in the support; ``owner`` is p
        g_rows, g_p, g_q, g_w = [], [], [], []
        yy, xx = np.nonzero(support)
        k = 0
        for dy, dx in _N8:
            qy, qx = yy + dy, xx + dx
            ok = (qy >= 0) & (qy < hh) & (qx >= 0) & (qx < ww)
            ok[ok] &= support[qy[ok], qx[ok]]
            p = index[yy[ok] * ww + xx[ok]]
            q = index[qy[ok] * ww + qx[ok]]
            g_rows.append(np.arange(k, k + len(p)))
            g_p.append(p)
            g_q.append(q)
            g_w.append(np.full(len(p), 1.0 / math.hypot(dy, dx)))
            k += len(p)
        gr = np.concatenate(g_rows)
        gw = np.concatenate(g_w)
        self.owner = np.concatenate(g_p)
        self.G = sparse.csr_matrix(
            (
                np.concatenate([gw, -gw]),
                (np.concatenate([gr, gr]), np.concatenate([self.owner, np.concatenate(g_q)])),
            ),
            shape=(k, n),
        )
        self.n = n
        self.lam = lam
        self.eps2 = eps_mm**2

    def norms(self, x: np.ndarray) -> np.ndarray:
        g = self.G @ x
        return np.sqrt(np.bincount(self.owner, g * g, minlength=self.n) + self.eps2)

    def energy(self, x: np.ndarray) -> float:
        res = self.A @ x - self.y
        return float(res @ res + self.lam * self.norms(x).sum())

    def step(self, x: np.ndarray, cg_iterations: int, mu: float = 1e-3) -> np.ndarray:
        """One majorise–minimise step (lagged diffusivity / IRLS), solved by CG.

        sqrt(s) ≤ (s + s₀)/(2 sqrt(s₀)) makes the quadratic
        ‖A x − y‖² + (λ/2) Σ_p w_p Σ_o ((x_p − x_{p+o})/|o|)² + μ‖x − x_k‖², w_p = 1/n_p(x_k),
        an upper bound of E touching it at x_k; CG started at x_k only lowers that bound, so E
        never increases.
        """
        w = 1.0 / self.norms(x)
        wg = sparse.diags(w[self.owner] * (0.5 * self.lam))
        m = (self.AtA + self.G.T @ wg @ self.G + sparse.identity(self.n) * mu).tocsr()
        b = self.Aty + mu * x
        diag = m.diagonal()
        return _pcg(m, b, x.copy(), 1.0 / np.where(diag > 0, diag, 1.0), cg_iterations)


def _pcg(
    m: sparse.csr_matrix,
    b: np.ndarray,
    x: np.ndarray,
    inv_diag: np.ndarray,
    iterations: int,
    rtol: float = 1e-6,
) -> np.ndarray:
    """Jacobi-preconditioned conjugate gradients for the SPD system m x = b, started at x.

    The textbook algorithm (as ``scipy.sparse.linalg.cg``), with the inner products written as
    element-wise sums: multithreaded BLAS level-1 calls cost more than they compute on
    systems of this size. Each iterate lowers ½xᵀmx − bᵀx.
    """
    res = b - m @ x
    z = inv_diag * res
    p = z.copy()
    rz = float((res * z).sum())
    stop = rtol * math.sqrt(float((b * b).sum()))
    for _ in range(iterations):
        if math.sqrt(float((res * res).sum())) <= stop or rz <= 0:
            break
        mp = m @ p
        alpha = rz / float((p * mp).sum())
        x += alpha * p
        res -= alpha * mp
        z = inv_diag * res
        rz_new = float((res * z).sum())
        p = z + (rz_new / rz) * p
        rz = rz_new
    return x


def lidarboost(
    lowres: npt.ArrayLike,
    r: int,
    n_frames: int = 9,
    *,
    lam: float = 30.0,
    iterations: int = 10,
    eps_mm: float = 1.0,
    cg_iterations: int = 60,
    flows: FlowPair | None = None,
    config: UPSRConfig | None = None,
    callback: EnergyCallback | None = None,
) -> np.ndarray:
    r"""LidarBoost multi-frame depth super-resolution (Schuon, Theobalt, Davis, Thrun 2009).

    Schuon et al., "LidarBoost: depth superresolution for ToF 3D shape scanning", CVPR 2009:
    the high-res depth x of the reference frame minimises a data-fidelity term over the
    registered frames plus a geometry prior. Written with the operators of ``SPEC.md`` §1,

    .. math::
        E(x) = \sum_t \|W_t \odot (D M_t x - y_t)\|_2^2
               + \lambda \sum_p \sqrt{\sum_{o \in N_8} \Big(\frac{x_p - x_{p+o}}{|o|}\Big)^2
               + \varepsilon^2}

    * M_t moves x to frame t with the motion of UP-SR (the frame → reference flows composed
      from the consecutive flows between upsampled frames, :func:`upsampled_flows`; Schuon et
      al. register their frames by optical flow too), and D samples it at the low-res pixel
      centres: each valid sample y_t(i, j) is compared with x read bilinearly where the sample
      lands on the reference grid. This is LidarBoost's W_k ⊙ (D_k − X), which compares every
      sample only with the high-res positions it is resampled to.
    * W_t (LidarBoost's W_k, T_k) removes invalid samples (0, no return) and samples that fall
      outside the image or outside the support (below).
    * Γ (their regulariser) is the sum over pixels of the ℓ2 norm of the vector of the 8
      finite differences to the 3×3 neighbours, each divided by the distance to the neighbour
      (an isotropic total variation on an 8-neighbourhood: it favours piecewise-smooth
      surfaces and keeps sharp edges). ε (mm) smooths the norm at 0.

    Solver: majorise–minimise (iteratively reweighted least squares, "lagged diffusivity"),
    each quadratic bound minimised by Jacobi-preconditioned conjugate gradients started at the
    current estimate (:func:`_pcg`), so the energy never increases. Start: the median
    Shift & Add image (:func:`shift_add`, ``fill=True``).

    The support — the pixels that are solved for, 0 elsewhere — is where the filled Shift &
    Add image shows depth: no depth is invented where the samples say "no return"; differences
    across its border are not regularised.

    Parameters
    ----------
    lowres : array_like, shape (T, h, w) or (h, w)
        Depth video (mm); 0 or NaN = invalid.
    r : int
        SR factor ≥ 1.
    n_frames : int
        Window length N (clipped to T), reference in the middle.
    lam : float
        λ ≥ 0 (mm: the data term is in mm², Γ in mm). The default was the best of 5–80 on
        :func:`upsr.research.synth.dynamic_scene` videos with σ = 30 mm noise at r = 4
        (20–40 alike).
    iterations : int
        Majorise–minimise iterations (≥ 0; 0 returns the starting image).
    eps_mm : float
        Smoothing ε > 0 of the regulariser's norm (mm).
    cg_iterations : int
        Conjugate-gradient iterations per step.
    flows : (forward, backward), optional
        Precomputed consecutive flows, see :func:`upsampled_flows`.
    config : UPSRConfig, optional
        Motion parameters used when ``flows`` is None.
    callback : callable, optional
        Called as ``callback(t, k, E)`` with the energy of reference frame t before the first
        (k = 0) and after every iteration k.

    Returns
    -------
    ndarray of float32, shape (T, r·h, r·w) (or (r·h, r·w) for one frame); 0 = unknown.
    """
    r = _check_scale(r)
    n_frames = _check_n_frames(n_frames)
    lam = float(lam)
    if not (math.isfinite(lam) and lam >= 0):
        raise InputError(f"lam must be a finite number >= 0, got {lam!r}")
    if not (math.isfinite(eps_mm) and eps_mm > 0):
        raise InputError(f"eps_mm must be a finite number > 0, got {eps_mm!r}")
    for name, value in (("iterations", iterations), ("cg_iterations", cg_iterations)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
            raise InputError(f"{name} must be an integer >= 0, got {value!r}")
    frames, single = _as_frames(lowres)
    outs = []
    for t, (win, maps) in enumerate(_windows(frames, r, n_frames, flows, config)):
        start, _ = _shift_add_frame(win, maps, r, fill=True)
        support = start > 0
        out = np.zeros_like(start)
        if support.any():
            prob = _LidarBoostProblem(win, maps, r, support, lam, float(eps_mm))
            x = start[support].astype(np.float64)
            if callback is not None:
                callback(t, 0, prob.energy(x))
            for k in range(int(iterations)):
                x = prob.step(x, int(cg_iterations))
                if callback is not None:
                    callback(t, k + 1, prob.energy(x))
            out[support] = np.maximum(x, 0.0)
        outs.append(out)
    res = np.stack(outs).astype(np.float32)
    return res[0] if single else res
