"""Example-based single depth image SR after Mac Aodha et al. 2012 ("patch-based SISR" [12]
of the paper): :class:`PatchSISR`, its dictionary from rendered synthetic depth
(:func:`train_patch_sisr`) and :func:`patch_sisr`.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import numpy.typing as npt
from scipy.spatial import cKDTree

from upsr.errors import InputError
from upsr.geometry.camera import PinholeCamera
from upsr.geometry.rendering import render_depth
from upsr.method.upsampling import _check_scale, upsample_nearest
from upsr.research.baselines._common import _as_frames
from upsr.research.metrics import _check_mm
from upsr.research.synth.primitives import box, merge

__all__ = [
    "PatchSISR",
    "patch_sisr",
    "train_patch_sisr",
]


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
    parts = []
    tan_x = (camera.width / 2.0) / camera.fx
    tan_y = (camera.height / 2.0) / camera.fy
    for _ in range(int(rng.integers(2, 7))):
        z = rng.uniform(0.8, 4.0)
        centre = np.array([rng.uniform(-1, 1) * tan_x * z, rng.uniform(-1, 1) * tan_y * z, z])
        kind = rng.integers(3)
        if kind == 0:
            verts, faces = box(np.zeros(3), 0.5 * rng.uniform(0.08, 0.3, 3) * z)
        elif kind == 1:
            verts, faces = _sphere_mesh()
            verts = verts * rng.uniform(0.04, 0.25) * z
        else:  # a thin plate: a plane patch at a random orientation
            verts, faces = box(np.zeros(3), 0.5 * np.array([*rng.uniform(0.1, 0.4, 2) * z, 0.005]))
        parts.append((verts @ _rotation(rng).T + centre, faces))
    wall = None
    if rng.random() < 0.85:
        normal = np.array([rng.uniform(-0.6, 0.6), rng.uniform(-0.6, 0.6), 1.0])
        wall = (normal, float(rng.uniform(2500.0, 6000.0)))
    return (*merge(parts), wall)


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
    :func:`upsr.geometry.rendering.render_depth` by a pinhole camera at the low resolution and
    at r times that (:meth:`~upsr.geometry.camera.PinholeCamera.scaled`, the pixel geometry of
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
