"""The methods the paper compares UP-SR against (paper §7.3–7.4, Fig. 3–6).

Single frame
    :func:`nearest` (dense upsampling U on its own), :func:`bicubic` (naive), and
    :func:`bicubic_noflying` (bicubic with the flying pixels removed by a fixed threshold, §7.4);
    :func:`joint_bilateral_upsampling` (Kopf et al. 2007, the "2-D/depth fusion" of Fig. 4 (c)),
    guided by a high-res colour or grey image; :func:`patch_sisr` / :class:`PatchSISR`
    (example-based single-image SR after Mac Aodha et al. 2012, "patch-based SISR" [12]).
Multi-frame, with the motion of UP-SR
    :func:`shift_add` (dynamic median Shift & Add, Farsiu et al. 2004, "dynamic S&A" [41]) and
    :func:`lidarboost` (Schuon et al. 2009). Both use the consecutive flows between *upsampled*
    frames that UP-SR estimates (:func:`upsampled_flows`, paper §4, §5.2), chained by
    composition (:mod:`upsr.method.registration`); precomputed flows may be passed instead.

Everything uses the pixel geometry of ``SPEC.md`` §1: low-res pixel (i, j) sits at high-res
coordinate ((i + 0.5)·r − 0.5, (j + 0.5)·r − 0.5). Depth is float32 mm, 0 = unknown.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Iterator

import cv2
import numba as nb
import numpy as np
import numpy.typing as npt
from scipy import ndimage, sparse
from scipy.spatial import cKDTree

from upsr.errors import InputError
from upsr.geometry.camera import PinholeCamera
from upsr.geometry.rendering import render_depth
from upsr.method.config import UPSRConfig
from upsr.method.deblurring import estimate_noise_mm
from upsr.method.motion import (
    bilateral_prefilter,
    depth_range,
    depth_to_u8,
    make_flow_backend,
    suppress_spurious_motion,
)
from upsr.method.registration import flows_to_reference
from upsr.method.upsampling import upsample_bicubic, upsample_nearest
from upsr.method.validation import as_depth_frame
from upsr.research.metrics import _check_mm

__all__ = [
    "PatchSISR",
    "bicubic",
    "bicubic_noflying",
    "joint_bilateral_upsampling",
    "lidarboost",
    "nearest",
    "patch_sisr",
    "shift_add",
    "train_patch_sisr",
    "upsampled_flows",
]

#: Consecutive flows of a video on the high-res grid: ``(forward, backward)``, each of shape
#: (T−1, r·h, r·w, 2); ``forward[t]`` maps frame t to t+1, ``backward[t]`` frame t+1 to t.
FlowPair = tuple[np.ndarray, np.ndarray]


def _check_scale(r: int) -> int:
    if isinstance(r, bool) or not isinstance(r, (int, np.integer)) or r < 1:
        raise InputError(f"scale r must be an integer >= 1, got {r!r}")
    return int(r)


def _as_frames(lowres: npt.ArrayLike) -> tuple[np.ndarray, bool]:
    """(T, h, w) float32 with invalid = 0, and whether the input was a single (h, w) frame."""
    arr = np.asarray(lowres)
    if arr.ndim == 2:
        return as_depth_frame(arr, name="lowres")[None], True
    if arr.ndim == 3 and arr.shape[0] > 0:
        return np.stack(
            [as_depth_frame(f, name=f"lowres frame {t}") for t, f in enumerate(arr)]
        ), False
    raise InputError(
        f"lowres: expected a depth frame (h, w) or video (T, h, w), got shape {arr.shape}"
    )


def nearest(lowres: npt.ArrayLike, r: int) -> np.ndarray:
    """Nearest-neighbour upsampling: each low-res pixel becomes an r×r block.

    The dense upsampling U of UP-SR (paper eq. 13–15) used on its own, one frame at a time.
    It keeps edges and invalid pixels (0) exactly where the low-res frame has them and
    creates no new depth values.

    Parameters
    ----------
    lowres : array_like, shape (h, w) or (T, h, w)
        Depth (mm); 0 or NaN = invalid (NaN becomes 0).
    r : int
        SR factor ≥ 1.

    Returns
    -------
    ndarray of float32, shape (r·h, r·w) or (T, r·h, r·w).
    """
    r = _check_scale(r)
    frames, single = _as_frames(lowres)
    out = upsample_nearest(frames, r).astype(np.float32, copy=False)
    return out[0] if single else out


def bicubic(lowres: npt.ArrayLike, r: int) -> np.ndarray:
    """Naive bicubic interpolation, the conventional baseline of paper §7 (Fig. 3 (b), 6).

    ``cv2.resize`` with ``INTER_CUBIC`` per frame (half-pixel convention of ``SPEC.md`` §1,
    replicated border). Invalid pixels (0) are interpolated as if they were depth 0, as a naive
    bicubic would; the result is clipped at 0 (overshoot below 0 becomes "invalid"). Between
    foreground and background it creates intermediate depths: the *flying pixels* the paper
    criticises.

    Parameters
    ----------
    lowres : array_like, shape (h, w) or (T, h, w)
        Depth (mm); 0 or NaN = invalid (NaN becomes 0).
    r : int
        SR factor ≥ 1.

    Returns
    -------
    ndarray of float32, shape (r·h, r·w) or (T, r·h, r·w).
    """
    r = _check_scale(r)
    frames, single = _as_frames(lowres)
    out = upsample_bicubic(frames, r)
    return out[0] if single else out


# ------------------------------------------------------------------------------------------------
# Bicubic with the flying pixels removed (paper §7.4)
# ------------------------------------------------------------------------------------------------
def bicubic_noflying(lowres: npt.ArrayLike, r: int, threshold_mm: float = 100.0) -> np.ndarray:
    """Bicubic interpolation with its flying pixels removed by a fixed threshold (paper §7.4).

    The "modified bicubic interpolation" of paper §7.4 / Fig. 6: :func:`bicubic`, then every
    high-res pixel whose value is not supported by a nearby measurement is set to 0 (unknown).

    Rule: let N(p) be the valid low-res samples whose centres ((i + 0.5)·r − 0.5,
    (j + 0.5)·r − 0.5) lie within r high-res px of p in both directions (Chebyshev distance
    ≤ r, i.e. at most one low-res pixel away: the samples bicubic mostly interpolates between
    and the same (2r+1)² window as the flying-pixel metric of ``SPEC.md`` §6). The pixel keeps
    its bicubic value b(p) if ``min_{c ∈ N(p)} |b(p) − y(c)| ≤ threshold_mm`` and becomes 0
    otherwise (also when N(p) is empty). Values interpolated between a foreground and a
    background sample — or pulled towards 0 by a hole — are far from both and disappear;
    smooth surfaces keep their (noisy) interpolated depth.

    Parameters
    ----------
    lowres : array_like, shape (h, w) or (T, h, w)
        Depth (mm); 0 or NaN = invalid.
    r : int
        SR factor ≥ 1.
    threshold_mm : float
        The fixed threshold (mm), > 0. It should exceed the noise: with noise of std σ, about
        3σ keeps almost all surface pixels.

    Returns
    -------
    ndarray of float32, shape (r·h, r·w) or (T, r·h, r·w); 0 where removed or unknown.
    """
    r = _check_scale(r)
    threshold_mm = float(threshold_mm)
    if not (math.isfinite(threshold_mm) and threshold_mm > 0):
        raise InputError(f"threshold_mm must be a finite number > 0, got {threshold_mm!r}")
    frames, single = _as_frames(lowres)
    up = bicubic(frames, r)
    _, h, w = frames.shape
    hh, ww = h * r, w * r
    # high-res pixel → its low-res block (bi, bj) and the offset of its centre from the centre
    # of the low-res pixel (bi + di, bj + dj), in high-res px
    yy = np.arange(hh)
    xx = np.arange(ww)
    keep = np.zeros(up.shape, bool)
    for di in (-1, 0, 1):
        rows = yy // r + di
        dy = yy - ((rows + 0.5) * r - 0.5)
        row_ok = (rows >= 0) & (rows < h) & (np.abs(dy) <= r)
        rows_c = np.clip(rows, 0, h - 1)
        for dj in (-1, 0, 1):
            cols = xx // r + dj
            dx = xx - ((cols + 0.5) * r - 0.5)
            col_ok = (cols >= 0) & (cols < w) & (np.abs(dx) <= r)
            cols_c = np.clip(cols, 0, w - 1)
            sample = frames[:, rows_c[:, None], cols_c[None, :]]
            near = row_ok[:, None] & col_ok[None, :]
            keep |= near & (sample > 0) & (np.abs(up - sample) <= threshold_mm)
    out = np.where(keep & (up > 0), up, np.float32(0.0)).astype(np.float32)
    return out[0] if single else out


# ------------------------------------------------------------------------------------------------
# The motion of UP-SR, shared by the multi-frame baselines
# ------------------------------------------------------------------------------------------------
def upsampled_flows(lowres: npt.ArrayLike, r: int, *, config: UPSRConfig | None = None) -> FlowPair:
    """Consecutive optical flows between the *upsampled* frames, as UP-SR estimates them.

    Paper §4 and §5.2, steps 1–3 of ``SPEC.md`` §2: each frame is densely upsampled
    (nearest, eq. 13–15), bilateral-prefiltered and mapped to 8 bit with one fixed depth range
    for the whole video (:mod:`upsr.method.motion`); the flow backend of ``config`` then runs between
    consecutive frames in both directions, and motion that the depth does not support is
    zeroed (:func:`upsr.method.motion.suppress_spurious_motion`), exactly as in
    :class:`upsr.method.windowed.UPSR` (except that the depth range comes from the whole video).

    Parameters
    ----------
    lowres : array_like, shape (T, h, w) (or one (h, w) frame: no flow)
        Depth video (mm); 0 or NaN = invalid.
    r : int
        SR factor ≥ 1: the flows live on the (r·h, r·w) grid.
    config : UPSRConfig, optional
        Prefilter, flow backend and spurious-motion parameters (``UPSRConfig(scale=r)`` by
        default).

    Returns
    -------
    (forward, backward) : tuple of ndarray float32, each (T−1, r·h, r·w, 2)
        ``forward[t]`` is the flow from frame t to frame t+1, ``backward[t]`` from t+1 to t
        (``flow[i, j] = (dx, dy)``, see :mod:`upsr.method.motion`).
    """
    r = _check_scale(r)
    frames, _ = _as_frames(lowres)
    cfg = config if config is not None else UPSRConfig(scale=r)
    t, h, w = frames.shape
    fwd = np.zeros((max(t - 1, 0), h * r, w * r, 2), np.float32)
    bwd = np.zeros_like(fwd)
    if t < 2:
        return fwd, bwd
    up = upsample_nearest(frames, r)
    sigma_px = (
        float(cfg.prefilter_sigma_px) if cfg.prefilter_sigma_px is not None else 0.75 * r + 0.5
    )
    pre = [bilateral_prefilter(u, cfg.prefilter_sigma_mm, sigma_px) for u in up]
    near, far = cfg.depth_range_mm if cfg.depth_range_mm is not None else depth_range(frames)
    guides = [depth_to_u8(p, near, far) for p in pre]
    noise_mm = float(np.median([estimate_noise_mm(f) for f in frames]))
    backend = make_flow_backend(cfg.flow, cfg.flow_preset)

    def one(a: int, b: int) -> np.ndarray:
        flow = backend(guides[a], guides[b])
        if cfg.zero_motion_tolerance is not None:
            flow = suppress_spurious_motion(
                pre[a],
                pre[b],
                flow,
                window_px=2 * r + 1,
                tolerance=cfg.zero_motion_tolerance,
                noise_mm=noise_mm,
            )
        return flow

    for k in range(t - 1):
        fwd[k] = one(k, k + 1)
        bwd[k] = one(k + 1, k)
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
        fwd, bwd = upsampled_flows(frames, r, config=config)
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
        :func:`upsr.research.synth.dynamic_scene` videos with σ = 30 mm noise at r = 4 (20–40 alike).
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


# ------------------------------------------------------------------------------------------------
# Joint bilateral upsampling (Kopf et al. 2007)
# ------------------------------------------------------------------------------------------------
@nb.njit(cache=True, nogil=True, parallel=True)
def _jbu_kernel(depth, guide_hr, guide_lr, r, radius, inv_2ss, inv_2sr, out):  # pragma: no cover
    h, w = depth.shape
    hh, ww, nc = guide_hr.shape
    for y in nb.prange(hh):
        py = (y + 0.5) / r - 0.5  # position of the high-res pixel in low-res pixel units
        ci = math.floor(py + 0.5)
        for x in range(ww):
            px = (x + 0.5) / r - 0.5
            cj = math.floor(px + 0.5)
            # exponents first, then weights relative to the largest (no underflow to 0/0)
            best = -np.inf
            for i in range(max(ci - radius, 0), min(ci + radius + 1, h)):
                for j in range(max(cj - radius, 0), min(cj + radius + 1, w)):
                    if depth[i, j] > 0:
                        ds2 = ((py - i) ** 2 + (px - j) ** 2) * (r * r)
                        dc2 = 0.0
                        for c in range(nc):
                            dc2 += (guide_hr[y, x, c] - guide_lr[i, j, c]) ** 2
                        e = -ds2 * inv_2ss - dc2 * inv_2sr
                        if e > best:
                            best = e
            if best == -np.inf:
                out[y, x] = 0.0
                continue
            num = 0.0
            den = 0.0
            for i in range(max(ci - radius, 0), min(ci + radius + 1, h)):
                for j in range(max(cj - radius, 0), min(cj + radius + 1, w)):
                    d = depth[i, j]
                    if d > 0:
                        ds2 = ((py - i) ** 2 + (px - j) ** 2) * (r * r)
                        dc2 = 0.0
                        for c in range(nc):
                            dc2 += (guide_hr[y, x, c] - guide_lr[i, j, c]) ** 2
                        wgt = math.exp(-ds2 * inv_2ss - dc2 * inv_2sr - best)
                        num += wgt * d
                        den += wgt
            out[y, x] = num / den


def _as_guide(guide: npt.ArrayLike, shape: tuple[int, int], name: str) -> np.ndarray:
    """A guide image as float32 (H, W, C), checked against the high-res ``shape``."""
    g = np.asarray(guide)
    if g.dtype == object or not (
        np.issubdtype(g.dtype, np.integer) or np.issubdtype(g.dtype, np.floating)
    ):
        raise InputError(f"{name}: guide must be a numeric image, got dtype {g.dtype}")
    if g.ndim == 2:
        g = g[..., None]
    if g.ndim != 3 or g.shape[:2] != shape:
        raise InputError(
            f"{name}: expected a guide image of shape {shape} or {(*shape, 'C')}, got {g.shape}"
        )
    g = g.astype(np.float32)
    if not np.isfinite(g).all():
        raise InputError(f"{name}: guide contains NaN or ±inf")
    return np.ascontiguousarray(g)


def joint_bilateral_upsampling(
    lowres_depth_frame: npt.ArrayLike,
    r: int,
    colour_hr: npt.ArrayLike,
    *,
    sigma_spatial_px: float | None = None,
    sigma_range: float | None = None,
) -> np.ndarray:
    r"""Joint bilateral upsampling of depth guided by a high-res image (Kopf et al. 2007).

    Kopf, Cohen, Lischinski, Uyttendaele, "Joint bilateral upsampling", ACM TOG 26(3) (SIGGRAPH
    2007), eq. 2; the "2-D/depth fusion" of the paper's Fig. 4 (c) ([5]):

    .. math::
        \tilde S_p = \frac{1}{k_p} \sum_{q_\downarrow \in \Omega} S_{q_\downarrow}\,
        f(\|p_\downarrow - q_\downarrow\|)\, g(\|\tilde I_p - \tilde I_q\|)

    p↓ is the position of the high-res pixel p on the low-res grid (``SPEC.md`` §1), q↓ runs
    over the low-res pixels of a (2R+1)² window around it, f and g are Gaussians of standard
    deviation ``sigma_spatial_px`` (distance measured in high-res px) and ``sigma_range``
    (guide units, Euclidean distance over the channels), k_p normalises the weights.
    Ĩ_q, the guide at the low-res sample q, is the mean of the guide over q's r×r block
    (what the low-res pixel covers). Invalid low-res pixels (0) get zero weight; a pixel
    with no valid sample in its window is 0. The window radius is R = ⌈2·σ_s / r⌉ low-res px
    (at least 1). Numba-compiled kernel, parallel over rows.

    Like any weighted average it mixes depths where the guide shows no edge, and it copies
    guide texture into the depth (the "texture copying" the paper notes).

    Parameters
    ----------
    lowres_depth_frame : array_like, shape (h, w) or (T, h, w)
        Depth (mm); 0 or NaN = invalid.
    r : int
        SR factor ≥ 1.
    colour_hr : array_like, shape (r·h, r·w), (r·h, r·w, C), or with a leading T for a video
        The registered high-res guide (colour or grey, any numeric range).
    sigma_spatial_px : float, optional
        Spatial σ in high-res px (default r: one low-res pixel).
    sigma_range : float, optional
        Range σ in guide units (default: 10 % of the guide's value range, at least 1e−6).

    Returns
    -------
    ndarray of float32, shape (r·h, r·w) (or (T, r·h, r·w)); 0 = unknown.
    """
    r = _check_scale(r)
    frames, single = _as_frames(lowres_depth_frame)
    t, h, w = frames.shape
    shape = (h * r, w * r)
    g = np.asarray(colour_hr)
    guides = [g] if single else list(g) if g.ndim >= 3 and len(g) == t else None
    if guides is None:
        raise InputError(
            f"colour_hr: a video of {t} depth frames needs {t} guide images, got shape {g.shape}"
        )
    sigma_s = float(r) if sigma_spatial_px is None else float(sigma_spatial_px)
    if not (math.isfinite(sigma_s) and sigma_s > 0):
        raise InputError(f"sigma_spatial_px must be a finite number > 0, got {sigma_spatial_px!r}")
    if sigma_range is not None and not (math.isfinite(sigma_range) and sigma_range > 0):
        raise InputError(f"sigma_range must be a finite number > 0, got {sigma_range!r}")
    radius = max(1, math.ceil(2.0 * sigma_s / r))
    outs = []
    for k, (depth, guide) in enumerate(zip(frames, guides, strict=True)):
        gh = _as_guide(guide, shape, f"colour_hr frame {k}" if not single else "colour_hr")
        sr = sigma_range
        if sr is None:
            sr = max(0.1 * float(gh.max() - gh.min()), 1e-6)
        gl = gh.reshape(h, r, w, r, gh.shape[2]).mean(axis=(1, 3), dtype=np.float64)
        out = np.empty(shape, np.float32)
        _jbu_kernel(
            np.ascontiguousarray(depth),
            gh,
            np.ascontiguousarray(gl, np.float32),
            r,
            radius,
            1.0 / (2.0 * sigma_s**2),
            1.0 / (2.0 * float(sr) ** 2),
            out,
        )
        outs.append(out)
    res = np.stack(outs)
    return res[0] if single else res


# ------------------------------------------------------------------------------------------------
# Example-based single-image SR (after Mac Aodha et al. 2012)
# ------------------------------------------------------------------------------------------------
_PATCH = 3  # low-res patch side (px)


def _rotation(rng: np.random.Generator) -> np.ndarray:
    """A uniformly random 3-D rotation matrix (from a random unit quaternion)."""
    q = rng.normal(size=4)
    a, b, c, d = q / np.linalg.norm(q)
    return np.array(
        [
            [a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c)],
            [2 * (b * c + a * d), a * a - b * b + c * c - d * d, 2 * (c * d - a * b)],
            [2 * (b * d - a * c), 2 * (c * d + a * b), a * a - b * b - c * c + d * d],
        ]
    )


_BOX_FACES = "0 1 3 0 3 2 4 6 7 4 7 5 0 4 5 0 5 1 2 3 7 2 7 6 0 2 6 0 6 4 1 5 7 1 7 3"


def _box_mesh(size: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """An axis-aligned box centred at the origin (12 triangles)."""
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    faces = np.array(_BOX_FACES.split(), np.intp).reshape(-1, 3)
    return corners * (0.5 * size), faces


def _sphere_mesh(n_lat: int = 12, n_lon: int = 18) -> tuple[np.ndarray, np.ndarray]:
    """A unit UV sphere."""
    lat = np.linspace(0, np.pi, n_lat + 1)[1:-1]
    lon = np.linspace(0, 2 * np.pi, n_lon, endpoint=False)
    ring = np.stack(
        [
            np.outer(np.sin(lat), np.cos(lon)),
            np.outer(np.sin(lat), np.sin(lon)),
            np.repeat(np.cos(lat)[:, None], n_lon, axis=1),
        ],
        axis=-1,
    ).reshape(-1, 3)
    verts = np.concatenate([[[0, 0, 1]], ring, [[0, 0, -1]]])
    faces = []
    for j in range(n_lon):
        k = (j + 1) % n_lon
        faces.append([0, 1 + j, 1 + k])
        for i in range(n_lat - 2):
            a, b = 1 + i * n_lon + j, 1 + i * n_lon + k
            faces += [[a, a + n_lon, b + n_lon], [a, b + n_lon, b]]
        last = 1 + (n_lat - 2) * n_lon
        faces.append([last + j, len(verts) - 1, last + k])
    return verts, np.array(faces)


def _training_geometry(
    rng: np.random.Generator, camera: PinholeCamera
) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, float] | None]:
    """A random scene of boxes, spheres and plates, usually before a slanted wall.

    Returns vertices (m, camera frame), triangles and the wall for :func:`render_depth`.
    """
    verts_all, faces_all = [], []
    n_v = 0
    tan_x = (camera.width / 2.0) / camera.fx
    tan_y = (camera.height / 2.0) / camera.fy
    for _ in range(int(rng.integers(2, 7))):
        z = rng.uniform(0.8, 4.0)
        centre = np.array([rng.uniform(-1, 1) * tan_x * z, rng.uniform(-1, 1) * tan_y * z, z])
        kind = rng.integers(3)
        if kind == 0:
            verts, faces = _box_mesh(rng.uniform(0.08, 0.3, 3) * z)
        elif kind == 1:
            verts, faces = _sphere_mesh()
            verts = verts * rng.uniform(0.04, 0.25) * z
        else:  # a thin plate: a plane patch at a random orientation
            verts, faces = _box_mesh(np.array([*rng.uniform(0.1, 0.4, 2) * z, 0.005]))
        verts_all.append(verts @ _rotation(rng).T + centre)
        faces_all.append(faces + n_v)
        n_v += len(verts)
    wall = None
    if rng.random() < 0.85:
        normal = np.array([rng.uniform(-0.6, 0.6), rng.uniform(-0.6, 0.6), 1.0])
        wall = (normal, float(rng.uniform(2500.0, 6000.0)))
    return np.concatenate(verts_all), np.concatenate(faces_all), wall


def _dihedral(a: np.ndarray) -> list[np.ndarray]:
    """The 8 rotations / reflections of square patches stacked as (n, s, s)."""
    out = []
    for b in (a, a.transpose(0, 2, 1)):
        for k in range(4):
            out.append(np.rot90(b, k, axes=(1, 2)))
    return out


class PatchSISR:
    """Example-based single depth image SR after Mac Aodha et al. 2012, without the MRF.

    Mac Aodha, Campbell, Nair, Brostow, "Patch based synthesis for single depth image
    super-resolution", ECCV 2012 (the paper's "patch-based SISR" [12]): a dictionary of
    (low-res patch → high-res patch) pairs from synthetic depth; each low-res patch of the
    input, normalised for its depth offset, is matched to the dictionary and the high-res
    candidates are composed into the output. This version replaces their MRF labelling by a
    median and adds a depth guard so that no output lies between two surfaces. Exactly:

    * clean-up: a valid low-res sample that is ``guard_connect_mm`` or more away from each of
      its valid 8-neighbours, and half that from each valid sample two pixels away (the outer
      ring of its 5×5 neighbourhood), matches no surface there (a noise outlier); it is
      replaced by the depth of its closest valid 8-neighbour (a depth present there);
    * feature: the 3×3 low-res patch around each low-res pixel minus its mean (mm);
    * candidates: the ``k`` nearest dictionary patches (Euclidean, ``scipy.spatial.cKDTree``),
      each a high-res patch covering the low-res pixel and ``overlap`` low-res pixels around
      it ((2·overlap + 1)·r px square), minus its training mean, plus the query's mean;
    * composition: every high-res pixel takes the (lower) median of all the candidate values
      that cover it (k candidates × (2·overlap + 1)² overlapping patches);
    * depth guard: a candidate whose training edge has another height than the query's edge
      lands, once shifted by the query's mean, between (or beyond) the query's two surfaces
      (flying pixels). So every high-res pixel is checked against the (up to) four valid
      low-res samples around it (the cell of its position (y + 0.5)/r − 0.5,
      (x + 0.5)/r − 0.5, ``SPEC.md`` §1; clamped at the border, its own low-res pixel is
      always one of them): its value may be within ``guard_margin_mm`` of one of their
      depths, or between two of them that are less than ``guard_connect_mm`` apart (one
      surface, e.g. a slope); otherwise it is moved to the nearest such depth. Nothing is
      interpolated across a larger jump;
    * patches with an invalid (0) sample are not matched; pixels no candidate covers keep the
      nearest-neighbour upsampling (of the cleaned-up input); invalid pixels of the input stay
      0.

    Normalising the contrast too (dividing patches by their range, the high-res candidate
    rescaled by the query's range) was tried for the edge-height mismatch: on the Samba noise
    experiment it gained nothing once the guard is on and was worse with noise (noise then
    reads as contrast), so patches are matched in mm after removing the mean.

    Build one with :func:`train_patch_sisr`; call it on a frame or a video.

    Parameters
    ----------
    scale : int
        SR factor r the dictionary was built for.
    lowres_patches : ndarray, shape (n, 9)
        Mean-normalised low-res patches (mm).
    highres_patches : ndarray, shape (n, ((2·overlap + 1)·r)²)
        The matching high-res patches minus the low-res patch mean (mm).
    k : int
        Candidates per patch.
    overlap : int
        0 or 1: margin of the high-res patches around their low-res pixel (low-res px).
    guard_margin_mm : float
        Tolerance of the depth guard around a low-res depth (mm, ≥ 0).
    guard_connect_mm : float or None
        Neighbouring low-res depths closer than this (mm) belong to one surface (the guard
        allows the values between them; a sample this far from all its neighbours is an
        outlier); ``None`` switches the clean-up and the guard off (the plain method).
    """

    def __init__(
        self,
        scale: int,
        lowres_patches: npt.ArrayLike,
        highres_patches: npt.ArrayLike,
        *,
        k: int = 4,
        overlap: int = 1,
        guard_margin_mm: float = 30.0,
        guard_connect_mm: float | None = 100.0,
    ) -> None:
        self.scale = _check_scale(scale)
        if overlap not in (0, 1):
            raise InputError(f"overlap must be 0 or 1, got {overlap!r}")
        side = (2 * overlap + 1) * self.scale
        lo = np.ascontiguousarray(lowres_patches, np.float32)
        hi = np.ascontiguousarray(highres_patches, np.float32)
        if lo.ndim != 2 or lo.shape[1] != _PATCH * _PATCH or len(lo) == 0:
            raise InputError(f"lowres_patches must have shape (n, 9), got {lo.shape}")
        if hi.shape != (len(lo), side * side):
            raise InputError(
                f"highres_patches must have shape ({len(lo)}, {side * side}), got {hi.shape}"
            )
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 1 <= k <= len(lo):
            raise InputError(f"k must be an integer in [1, {len(lo)}], got {k!r}")
        self.guard_margin_mm = _check_mm(guard_margin_mm, "guard_margin_mm")
        self.guard_connect_mm = (
            None if guard_connect_mm is None else _check_mm(guard_connect_mm, "guard_connect_mm")
        )
        self.k = int(k)
        self.overlap = int(overlap)
        self.lowres_patches = lo
        self.highres_patches = hi
        self._tree = cKDTree(lo)

    @property
    def n_examples(self) -> int:
        """Number of (low-res, high-res) pairs in the dictionary."""
        return len(self.lowres_patches)

    def __call__(self, lowres: npt.ArrayLike) -> np.ndarray:
        """Same as :meth:`super_resolve`."""
        return self.super_resolve(lowres)

    def super_resolve(self, lowres: npt.ArrayLike) -> np.ndarray:
        """Super-resolve a depth frame (h, w) or each frame of a video (T, h, w) by r.

        Returns
        -------
        ndarray of float32, shape (r·h, r·w) or (T, r·h, r·w); 0 = unknown.
        """
        frames, single = _as_frames(lowres)
        out = np.stack([self._frame(f) for f in frames])
        return out[0] if single else out

    def _frame(self, f: np.ndarray) -> np.ndarray:
        r, ov, k = self.scale, self.overlap, self.k
        h, w = f.shape
        n_sub = 2 * ov + 1
        if self.guard_connect_mm is not None:
            f = _replace_isolated(f, self.guard_connect_mm)
        padded = np.pad(f, 1, mode="edge")
        patches = np.lib.stride_tricks.sliding_window_view(padded, (_PATCH, _PATCH))
        patches = patches.reshape(h * w, _PATCH * _PATCH)
        ok = (patches > 0).all(axis=1)
        fallback = upsample_nearest(f, r)
        if not ok.any():
            return fallback
        query = patches[ok]
        mean = query.mean(axis=1, dtype=np.float64).astype(np.float32)
        _, idx = self._tree.query(query - mean[:, None], k=k)
        idx = np.asarray(idx).reshape(-1, k)
        cand = self.highres_patches[idx] + mean[:, None, None]  # (m, k, side²)
        pred = np.full((h * w, k, n_sub, r, n_sub, r), np.nan, np.float32)
        pred[ok] = cand.reshape(-1, k, n_sub, r, n_sub, r)
        pred = pred.reshape(h, w, k, n_sub, r, n_sub, r)
        # votes[a, b] for the low-res block (u, v) come from the patch (u + ov − a, v + ov − b)
        votes = np.full((n_sub, n_sub, k, h, r, w, r), np.nan, np.float32)
        for a in range(n_sub):
            du = ov - a
            for b in range(n_sub):
                dv = ov - b
                src = pred[:, :, :, a, :, b, :]  # (h, w, k, r, r)
                us = slice(max(-du, 0), h - max(du, 0))
                vs = slice(max(-dv, 0), w - max(dv, 0))
                sub = src[max(du, 0) : h + min(du, 0), max(dv, 0) : w + min(dv, 0)]
                votes[a, b, :, us, :, vs, :] = sub.transpose(2, 0, 3, 1, 4)
        votes = votes.reshape(n_sub * n_sub * k, h * r, w * r)
        n_votes = np.count_nonzero(~np.isnan(votes), axis=0)
        votes.sort(axis=0)  # NaN last
        lower = np.take_along_axis(votes, np.maximum(n_votes - 1, 0)[None] // 2, axis=0)[0]
        out = np.where(n_votes > 0, lower, fallback)
        if self.guard_connect_mm is not None:
            out = _depth_guard(out, f, r, self.guard_connect_mm, self.guard_margin_mm)
        out[fallback <= 0] = 0.0
        return np.maximum(out, 0.0).astype(np.float32)


def _replace_isolated(f: np.ndarray, jump_mm: float) -> np.ndarray:
    """Replace the valid samples that match no surface around them (noise outliers).

    Isolated: ≥ ``jump_mm`` from each valid 8-neighbour and ≥ ``jump_mm``/2 from each valid
    sample of the outer ring of the 5×5 neighbourhood (so that a correct sample whose only
    same-surface 8-neighbour is itself an outlier is kept). An isolated sample becomes the
    depth of its closest valid 8-neighbour (a depth present right there, on the surface the
    sample most likely belongs to). Samples without a valid 8-neighbour and invalid ones are
    kept.
    """
    h, w = f.shape
    padded = np.pad(f, 2)
    offsets = [(dy, dx) for dy in range(-2, 3) for dx in range(-2, 3) if dy or dx]
    nbrs = np.stack([padded[2 + dy : 2 + dy + h, 2 + dx : 2 + dx + w] for dy, dx in offsets])
    valid = nbrs > 0
    ring1 = np.array([max(abs(dy), abs(dx)) == 1 for dy, dx in offsets])
    diff = np.where(valid, np.abs(nbrs - f), np.inf)
    near = (diff[ring1] < jump_mm).any(axis=0) | (diff[~ring1] < 0.5 * jump_mm).any(axis=0)
    isolated = (f > 0) & valid[ring1].any(axis=0) & ~near
    if not isolated.any():
        return f
    cols = np.argmin(diff[ring1][:, isolated], axis=0)
    out = f.copy()
    out[isolated] = nbrs[ring1][:, isolated][cols, np.arange(len(cols))]
    return out


def _depth_guard(
    out: np.ndarray, lowres: np.ndarray, r: int, connect_mm: float, margin_mm: float
) -> np.ndarray:
    """Move every high-res value onto the depths its cell of low-res samples allows.

    The high-res pixel (y, x) lies in the cell of the low-res samples around low-res
    coordinate ((y + 0.5)/r − 0.5, (x + 0.5)/r − 0.5) (``SPEC.md`` §1; clamped at the border,
    its own low-res pixel is always one of them). Allowed: within ``margin_mm`` of a valid
    corner depth, or between two valid corners less than ``connect_mm`` apart (one surface);
    a value outside is moved to the nearest allowed depth.
    """
    h, w = lowres.shape
    rows = np.floor((np.arange(h * r) + 0.5) / r - 0.5).astype(np.intp)
    cols = np.floor((np.arange(w * r) + 0.5) / r - 0.5).astype(np.intp)
    y0, x0 = np.clip(rows, 0, h - 1), np.clip(cols, 0, w - 1)
    y1, x1 = np.minimum(y0 + 1, h - 1), np.minimum(x0 + 1, w - 1)
    corners = [lowres[yy][:, xx] for yy in (y0, y1) for xx in (x0, x1)]
    best = np.full(out.shape, np.inf, np.float32)
    moved = out.copy()
    for a in range(4):
        for b in range(a, 4):
            da, db = corners[a], corners[b]
            ok = (da > 0) & (db > 0)
            if a != b:
                ok &= np.abs(da - db) < connect_mm
            target = np.clip(out, np.minimum(da, db) - margin_mm, np.maximum(da, db) + margin_mm)
            dist = np.where(ok, np.abs(target - out), np.inf)
            take = dist < best
            best[take] = dist[take]
            moved[take] = target[take]
    return moved


def train_patch_sisr(
    r: int = 4,
    n_examples: int = 60000,
    seed: int = 0,
    *,
    k: int = 4,
    overlap: int = 1,
    noise_sigma_mm: float = 0.0,
    lowres_shape: tuple[int, int] = (24, 32),
    fov_x_deg: float = 60.0,
    guard_margin_mm: float = 30.0,
    guard_connect_mm: float | None = 100.0,
) -> PatchSISR:
    """Build a :class:`PatchSISR` dictionary from rendered synthetic depth (no downloads).

    Random scenes of boxes, spheres and thin plates at random poses 0.8–4 m away, in front
    of a randomly slanted wall 2.5–6 m away (or of nothing: no return) are rendered with
    :func:`upsr.research.synth.render.render_depth` by a pinhole camera at the low resolution and at r
    times that (:meth:`~upsr.research.synth.render.PinholeCamera.scaled`, the pixel geometry of
    ``SPEC.md`` §1: both are point samples of the same scene). Every fully valid pair of a 3×3
    low-res patch and the high-res patch over it is a candidate, with its 8 rotations and
    reflections; half of the ``n_examples`` kept are taken from patches that straddle a depth
    edge (range > 100 mm), the rest from smooth ones. Deterministic for a given ``seed``.

    Parameters
    ----------
    r : int
        SR factor.
    n_examples : int
        Dictionary size (pairs).
    seed : int
        Seed of the scenes and of the selection.
    k, overlap : int
        See :class:`PatchSISR`.
    noise_sigma_mm : float
        Laplacian noise (std, mm) added to the low-res training patches (0: clean).
    lowres_shape : (int, int)
        Size of the rendered low-res images.
    fov_x_deg : float
        Horizontal field of view of the training camera (degrees).
    guard_margin_mm, guard_connect_mm : float
        See :class:`PatchSISR`.

    Returns
    -------
    PatchSISR
    """
    r = _check_scale(r)
    if isinstance(n_examples, bool) or not isinstance(n_examples, (int, np.integer)):
        raise InputError(f"n_examples must be an integer >= 1, got {n_examples!r}")
    if n_examples < 1:
        raise InputError(f"n_examples must be an integer >= 1, got {n_examples!r}")
    if not (math.isfinite(noise_sigma_mm) and noise_sigma_mm >= 0):
        raise InputError(f"noise_sigma_mm must be a finite number >= 0, got {noise_sigma_mm!r}")
    if overlap not in (0, 1):
        raise InputError(f"overlap must be 0 or 1, got {overlap!r}")
    rng = np.random.default_rng(seed)
    h, w = lowres_shape
    cam_lr = PinholeCamera.from_fov(w, h, fov_x_deg)
    cam_hr = cam_lr.scaled(r)
    side = (2 * overlap + 1) * r
    lo_list, hi_list = [], []
    n_edge = n_smooth = 0
    for _ in range(2000):
        if n_edge >= n_examples // 2 and n_edge + n_smooth >= n_examples:
            break
        verts, faces, wall = _training_geometry(rng, cam_lr)
        lr = render_depth(verts, faces, cam_lr, background_mm=wall)
        hr = render_depth(verts, faces, cam_hr, background_mm=wall)
        lo = np.lib.stride_tricks.sliding_window_view(lr, (_PATCH, _PATCH)).reshape(-1, 3, 3)
        start = r * (1 - overlap)
        hi = np.lib.stride_tricks.sliding_window_view(hr[start:, start:], (side, side))
        hi = hi[::r, ::r][: h - 2, : w - 2].reshape(-1, side, side)
        ok = (lo > 0).all(axis=(1, 2)) & (hi > 0).all(axis=(1, 2))
        lo_aug = np.concatenate(_dihedral(lo[ok])).reshape(-1, 9)
        hi_aug = np.concatenate(_dihedral(hi[ok])).reshape(-1, side * side)
        lo_list.append(lo_aug)
        hi_list.append(hi_aug)
        edge = np.ptp(lo_aug, axis=1) > 100.0
        n_edge += int(edge.sum())
        n_smooth += int((~edge).sum())
    lo_all = np.concatenate(lo_list)
    hi_all = np.concatenate(hi_list)
    edge = np.ptp(lo_all, axis=1) > 100.0
    e_idx, s_idx = np.flatnonzero(edge), np.flatnonzero(~edge)
    n_e = min(len(e_idx), max(n_examples // 2, n_examples - len(s_idx)))
    n_s = min(len(s_idx), n_examples - n_e)
    pick = np.concatenate(
        [rng.choice(e_idx, n_e, replace=False), rng.choice(s_idx, n_s, replace=False)]
    )
    lo_sel = lo_all[pick].astype(np.float64)
    if noise_sigma_mm > 0:
        lo_sel += rng.laplace(0.0, noise_sigma_mm / math.sqrt(2.0), lo_sel.shape)
    mean = lo_sel.mean(axis=1, keepdims=True)
    return PatchSISR(
        r,
        (lo_sel - mean).astype(np.float32),
        (hi_all[pick] - mean).astype(np.float32),
        k=k,
        overlap=overlap,
        guard_margin_mm=guard_margin_mm,
        guard_connect_mm=guard_connect_mm,
    )


@functools.lru_cache(maxsize=8)
def _default_patch_model(r: int) -> PatchSISR:
    return train_patch_sisr(r)


def patch_sisr(lowres: npt.ArrayLike, r: int, *, model: PatchSISR | None = None) -> np.ndarray:
    """Patch-based single-image SR (after Mac Aodha et al. 2012), see :class:`PatchSISR`.

    Parameters
    ----------
    lowres : array_like, shape (h, w) or (T, h, w)
        Depth (mm); 0 or NaN = invalid. Frames are processed independently.
    r : int
        SR factor ≥ 1.
    model : PatchSISR, optional
        A dictionary for factor r; default: ``train_patch_sisr(r)`` (built once per process).

    Returns
    -------
    ndarray of float32, shape (r·h, r·w) or (T, r·h, r·w); 0 = unknown.
    """
    r = _check_scale(r)
    if model is None:
        model = _default_patch_model(r)
    elif model.scale != r:
        raise InputError(f"the model was built for r = {model.scale}, not r = {r}")
    return model.super_resolve(lowres)
