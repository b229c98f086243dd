"""Analytic dynamic depth scenes with exact ground truth at any resolution.

The scene is a slanted wall (≈ 2500–3000 mm) with, in front of it, a non-rigidly moving object:
an ellipsoidal blob (≈ 1400–1800 mm) that translates by a non-integer number of low-res pixels
per frame and "breathes" (its radii oscillate), and an arm (a capsule, ≈ 1250–1450 mm) attached
to the blob's centre that rotates. Depth is the nearest surface along each ray (z-buffer), 0
where no surface is hit (no wall: ``background="none"``).

Coordinates are continuous and measured in **low-res pixels** from the top-left image corner:
low-res pixel (i, j) is centred at (y, x) = (i + 0.5, j + 0.5) and high-res pixel (k, l) at
scale r at ((k + 0.5)/r, (l + 0.5)/r). This is the pixel geometry of ``SPEC.md`` §1 (the low-res
centre sits at high-res coordinate (i + 0.5)·r − 0.5). Both the ground truth and the low-res
frames are point samples of the same analytic scene at their pixel centres (same field of
view); the low-res frames are *not* decimated high-res images.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
import numpy.typing as npt

import upsr.research.synth.degradation as _deg
from upsr.errors import InputError

__all__ = ["DynamicScene", "SyntheticVideo", "dynamic_scene", "make_scene"]

Background = Literal["wall", "none"]


def _reflect(p: float, lo: float, hi: float) -> float:
    """Fold ``p`` into [lo, hi] by mirror reflection (a ping-pong trajectory)."""
    if hi <= lo:
        return 0.5 * (lo + hi)
    span = hi - lo
    q = (p - lo) % (2 * span)
    return lo + (q if q <= span else 2 * span - q)


@dataclass(frozen=True)
class DynamicScene:
    """Parameters of the analytic scene; lengths in low-res px, depths in mm, time in frames.

    Attributes
    ----------
    lowres_shape : (int, int)
        Low-res image size (h, w); the field of view is [0, h] × [0, w] in low-res px.
    background : {"wall", "none"}
        A slanted wall behind the object, or nothing (depth 0, no return).
    wall_depth_mm, wall_tilt_x_mm, wall_tilt_y_mm : float
        Wall depth at the image centre and its total change across the width / height.
    centre_yx : (float, float)
        Blob centre at time ``t_mid``.
    velocity_yx : (float, float)
        Blob velocity (low-res px / frame); the centre bounces off the box that keeps the
        blob inside the image.
    t_mid : float
        Reference time of ``centre_yx`` (the middle frame).
    radii_yx : (float, float)
        Mean blob radii (low-res px).
    breathing, breathing_period, breathing_phase : float
        Relative amplitude, period (frames) and phase (rad) of the radii oscillation; the two
        radii oscillate in opposition, so the blob deforms, not just scales.
    blob_rim_mm, blob_bulge_mm : float
        Depth of the blob's silhouette and how much nearer its centre is.
    arm_length, arm_half_width : float
        Arm (capsule) length from the blob centre and half width (low-res px).
    arm_angle0, arm_speed : float
        Arm angle (rad) at t = 0 and angular speed (rad / frame).
    arm_near_mm, arm_far_mm : float
        Arm depth at its root and at its tip (linear in between).
    """

    lowres_shape: tuple[int, int] = (48, 64)
    background: Background = "wall"
    wall_depth_mm: float = 2750.0
    wall_tilt_x_mm: float = 300.0
    wall_tilt_y_mm: float = 150.0
    centre_yx: tuple[float, float] = (24.0, 32.0)
    velocity_yx: tuple[float, float] = (0.45, 1.5)
    t_mid: float = 4.0
    radii_yx: tuple[float, float] = (12.0, 11.0)
    breathing: float = 0.12
    breathing_period: float = 7.0
    breathing_phase: float = 0.0
    blob_rim_mm: float = 1800.0
    blob_bulge_mm: float = 400.0
    arm_length: float = 18.0
    arm_half_width: float = 1.6
    arm_angle0: float = 0.3
    arm_speed: float = 0.15
    arm_near_mm: float = 1250.0
    arm_far_mm: float = 1450.0

    def blob_state(self, t: float) -> tuple[float, float, float, float]:
        """Blob centre (y, x) and radii (ry, rx) in low-res px at time ``t`` (frames)."""
        h, w = self.lowres_shape
        ry0, rx0 = self.radii_yx
        amp = self.breathing
        phase = 2 * math.pi * t / self.breathing_period + self.breathing_phase
        ry = ry0 * (1 + amp * math.sin(phase))
        rx = rx0 * (1 - amp * math.sin(phase))
        margin_y = ry0 * (1 + amp)
        margin_x = rx0 * (1 + amp)
        dt = t - self.t_mid
        cy = _reflect(self.centre_yx[0] + self.velocity_yx[0] * dt, margin_y, h - margin_y)
        cx = _reflect(self.centre_yx[1] + self.velocity_yx[1] * dt, margin_x, w - margin_x)
        return cy, cx, ry, rx

    def depth_at(self, t: float, y: npt.ArrayLike, x: npt.ArrayLike) -> np.ndarray:
        """Depth (mm, float64) of the scene at time ``t`` at continuous points (y, x).

        Parameters
        ----------
        t : float
            Time in frames (non-integer allowed).
        y, x : array_like
            Broadcastable coordinates in low-res px from the top-left image corner.

        Returns
        -------
        ndarray of float64, the broadcast shape of ``y`` and ``x``; 0 where no surface is hit.
        """
        y = np.asarray(y, np.float64)
        x = np.asarray(x, np.float64)
        h, w = self.lowres_shape
        y, x = np.broadcast_arrays(y, x)
        z = np.full(y.shape, np.inf)
        if self.background == "wall":
            z = (
                self.wall_depth_mm
                + self.wall_tilt_x_mm * (x / w - 0.5)
                + self.wall_tilt_y_mm * (y / h - 0.5)
            )
        cy, cx, ry, rx = self.blob_state(t)
        q = ((y - cy) / ry) ** 2 + ((x - cx) / rx) ** 2
        inside = q < 1.0
        zb = self.blob_rim_mm - self.blob_bulge_mm * np.sqrt(np.clip(1.0 - q, 0.0, None))
        z = np.where(inside, np.minimum(z, zb), z)
        # the arm: a capsule around the segment from the blob centre, rotating
        angle = self.arm_angle0 + self.arm_speed * t
        dy, dx = math.sin(angle), math.cos(angle)
        s = np.clip(((y - cy) * dy + (x - cx) * dx) / self.arm_length, 0.0, 1.0)
        dist2 = (y - cy - s * self.arm_length * dy) ** 2 + (x - cx - s * self.arm_length * dx) ** 2
        on_arm = dist2 < self.arm_half_width**2
        za = self.arm_near_mm + (self.arm_far_mm - self.arm_near_mm) * s
        z = np.where(on_arm, np.minimum(z, za), z)
        return np.where(np.isfinite(z), z, 0.0)

    def render(self, t: float, scale: int = 1) -> np.ndarray:
        """Point-sample the scene at the pixel centres of an (r·h, r·w) image, float32 mm.

        ``scale=1`` gives the low-res frame; pixel (k, l) is sampled at
        ((k + 0.5)/r, (l + 0.5)/r) low-res px (``SPEC.md`` §1).
        """
        r = _check_int(scale, "scale", 1)
        h, w = self.lowres_shape
        ys = (np.arange(r * h) + 0.5) / r
        xs = (np.arange(r * w) + 0.5) / r
        return self.depth_at(t, ys[:, None], xs[None, :]).astype(np.float32)

    def render_video(self, n_frames: int, scale: int = 1) -> np.ndarray:
        """Frames t = 0 … n_frames − 1 as a float32 (T, r·h, r·w) video (mm)."""
        n = _check_int(n_frames, "n_frames", 1)
        return np.stack([self.render(t, scale) for t in range(n)])


@dataclass(frozen=True, eq=False)
class SyntheticVideo:
    """A synthetic low-res depth video with its high-res ground truth.

    Attributes
    ----------
    lowres : ndarray, float32 (T, h, w)
        Degraded input (mm): noise, optional mixed pixels and dropout; 0 = no return.
    lowres_clean : ndarray, float32 (T, h, w)
        The same low-res frames without any degradation.
    truth : ndarray, float32 (T, r·h, r·w)
        Ground truth (mm) at the high-res pixel centres; 0 = no surface.
    scale : int
        SR factor r.
    noise_sigma_mm : float
        Standard deviation σ of the Laplacian noise added to ``lowres`` (mm).
    scene : DynamicScene
        The analytic scene (evaluate it anywhere with :meth:`DynamicScene.depth_at`).
    seed : int
        Seed that produced the scene parameters and the noise.
    """

    lowres: np.ndarray
    lowres_clean: np.ndarray
    truth: np.ndarray
    scale: int
    noise_sigma_mm: float
    scene: DynamicScene
    seed: int

    @property
    def n_frames(self) -> int:
        """Number of frames T."""
        return int(self.lowres.shape[0])


def _check_int(value: int, name: str, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise InputError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def make_scene(
    lowres_shape: tuple[int, int] = (48, 64),
    *,
    n_frames: int = 9,
    background: Background = "wall",
    motion_px: float = 1.5,
    seed: int = 0,
) -> DynamicScene:
    """Scene parameters scaled to the image size, with a seed-dependent layout.

    Parameters
    ----------
    lowres_shape : (int, int)
        Low-res size (h, w), at least 8 × 8.
    n_frames : int
        Length of the video; the blob passes the image centre at the middle frame.
    background : {"wall", "none"}
    motion_px : float
        Blob speed (low-res px / frame), ≥ 0.
    seed : int
        Chooses the direction of motion, the arm's start angle and the breathing phase.
    """
    if not isinstance(lowres_shape, (tuple, list)) or len(lowres_shape) != 2:
        raise InputError(f"lowres_shape must be (h, w), got {lowres_shape!r}")
    h = _check_int(lowres_shape[0], "lowres_shape height", 8)
    w = _check_int(lowres_shape[1], "lowres_shape width", 8)
    n = _check_int(n_frames, "n_frames", 1)
    if background not in ("wall", "none"):
        raise InputError(f"background must be 'wall' or 'none', got {background!r}")
    motion_px = float(motion_px)
    if not (math.isfinite(motion_px) and motion_px >= 0):
        raise InputError(f"motion_px must be a finite number >= 0, got {motion_px!r}")
    seed = _check_int(seed, "seed", 0)
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(2)[0])
    direction = rng.uniform(-0.35, 0.35) + (math.pi if rng.random() < 0.5 else 0.0)
    size = min(h, w)
    return DynamicScene(
        lowres_shape=(h, w),
        background=background,
        centre_yx=(0.5 * h, 0.5 * w),
        velocity_yx=(motion_px * math.sin(direction), motion_px * math.cos(direction)),
        t_mid=0.5 * (n - 1),
        radii_yx=(0.25 * size, 0.23 * size),
        breathing_phase=float(rng.uniform(0, 2 * math.pi)),
        arm_length=0.38 * size,
        arm_half_width=max(1.0, 0.034 * size),
        arm_angle0=float(rng.uniform(0, 2 * math.pi)),
        arm_speed=0.15 if rng.random() < 0.5 else -0.15,
    )


def dynamic_scene(
    n_frames: int = 9,
    lowres_shape: tuple[int, int] = (48, 64),
    scale: int = 4,
    noise_sigma_mm: float = 20.0,
    background: Background = "wall",
    dropout: float = 0.0,
    seed: int = 0,
    motion_px: float = 1.5,
    *,
    flying_pixels: float = 0.0,
) -> SyntheticVideo:
    """Synthesise a dynamic depth video (non-rigid motion) with its high-res ground truth.

    Parameters
    ----------
    n_frames : int
        Number of frames T.
    lowres_shape : (int, int)
        Low-res frame size (h, w) in px.
    scale : int
        SR factor r; the truth is (r·h, r·w).
    noise_sigma_mm : float
        Standard deviation σ (mm) of the i.i.d. Laplacian noise added to the low-res frames
        (valid pixels only; the truth is noise-free).
    background : {"wall", "none"}
        "none": no wall, pixels that miss the object are 0 (no return) in input and truth.
    dropout : float
        Probability that a low-res pixel is lost (set to 0) after the noise.
    seed : int
        Seed of the scene layout and of the degradations (fully deterministic).
    motion_px : float
        Speed of the object (low-res px / frame).
    flying_pixels : float
        Probability that a low-res pixel at a depth edge is replaced by a foreground /
        background mix (ToF mixed pixels,
        :func:`~upsr.research.synth.degradation.flying_pixel_artefacts`).
        0 disables it.

    Returns
    -------
    SyntheticVideo
    """
    r = _check_int(scale, "scale", 1)
    seed = _check_int(seed, "seed", 0)
    scene = make_scene(
        lowres_shape, n_frames=n_frames, background=background, motion_px=motion_px, seed=seed
    )
    sigma = float(noise_sigma_mm)
    if not (math.isfinite(sigma) and sigma >= 0):
        raise InputError(f"noise_sigma_mm must be a finite number >= 0, got {noise_sigma_mm!r}")
    clean = scene.render_video(n_frames, 1)
    truth = scene.render_video(n_frames, r)
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(2)[1])
    lowres = clean
    if flying_pixels > 0:
        lowres = _deg.flying_pixel_artefacts(lowres, rng, probability=flying_pixels)
    lowres = _deg.add_laplacian_noise(lowres, sigma, rng)
    lowres = _deg.dropout(lowres, dropout, rng)
    return SyntheticVideo(
        lowres=lowres,
        lowres_clean=clean,
        truth=truth,
        scale=r,
        noise_sigma_mm=sigma,
        scene=scene,
        seed=int(seed),
    )
