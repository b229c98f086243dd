"""The ideal pinhole camera of every depth frame (OpenCV conventions, SPEC §1).

* Camera frame: x right, y down, z forward along the optical axis.
* Projection of a camera-frame point (X, Y, Z): u = fx·X/Z + cx (column), v = fy·Y/Z + cy (row).
* Pixel (i, j) (row i, column j) is sampled at its centre, image coordinates (u, v) = (j, i).
* Resolution changes follow ``SPEC.md`` §1: the low-res pixel i sits at the high-res coordinate
  (i + 0.5)·r − 0.5, so a camera scaled by s has f' = s·f and c' = s·(c + 0.5) − 0.5
  (:meth:`PinholeCamera.scaled`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction

import numpy as np
import numpy.typing as npt

from upsr.errors import InputError

__all__ = ["PinholeCamera"]


#: Bounds of intrinsics (px): absurd but finite values gave point clouds at ±inf, and a
#: focal length of 1e308 an inf once scaled by r (after the whole video was processed).
MIN_FOCAL_PX = 1e-3
MAX_INTRINSIC_PX = 1e9


@dataclass(frozen=True)
class PinholeCamera:
    """Ideal pinhole camera (no distortion).

    Attributes
    ----------
    fx, fy : float
        Focal lengths in px.
    cx, cy : float
        Principal point in px (image coordinates, pixel (i, j) centred at (u, v) = (j, i)).
    width, height : int
        Image size in px; rendered images have shape (height, width).
    """

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int

    def __post_init__(self) -> None:
        for name in ("fx", "fy", "cx", "cy"):
            val = getattr(self, name)
            if not math.isfinite(float(val)):
                raise InputError(f"camera {name} must be finite, got {val!r}")
            if abs(float(val)) > MAX_INTRINSIC_PX:  # (1e308: inf once scaled by r)
                raise InputError(f"camera {name} = {val:g} px is beyond {MAX_INTRINSIC_PX:g} px")
        if self.fx < MIN_FOCAL_PX or self.fy < MIN_FOCAL_PX:  # (1e-300: points at ±inf)
            raise InputError(
                f"focal lengths must be at least {MIN_FOCAL_PX:g} px, got fx={self.fx:g}, "
                f"fy={self.fy:g}"
            )
        for name in ("width", "height"):
            val = getattr(self, name)
            if isinstance(val, bool) or not isinstance(val, (int, np.integer)) or val < 1:
                raise InputError(f"camera {name} must be a positive integer, got {val!r}")

    @classmethod
    def from_fov(
        cls, width: int, height: int, fov_x_deg: float, *, fov_y_deg: float | None = None
    ) -> PinholeCamera:
        """Camera with the principal point at the image centre ((w−1)/2, (h−1)/2).

        Parameters
        ----------
        width, height : int
            Image size in px.
        fov_x_deg : float
            Horizontal field of view in degrees, edge to edge of the image (the outer borders of
            the first and last columns): fx = (width / 2) / tan(fov_x / 2).
        fov_y_deg : float, optional
            Vertical field of view; default: square pixels (fy = fx).
        """
        if not 0 < fov_x_deg < 180:
            raise InputError(f"fov_x_deg must be in (0, 180), got {fov_x_deg}")
        fx = (width / 2.0) / math.tan(math.radians(fov_x_deg) / 2.0)
        if fov_y_deg is None:
            fy = fx
        else:
            if not 0 < fov_y_deg < 180:
                raise InputError(f"fov_y_deg must be in (0, 180), got {fov_y_deg}")
            fy = (height / 2.0) / math.tan(math.radians(fov_y_deg) / 2.0)
        return cls(fx, fy, (width - 1) / 2.0, (height - 1) / 2.0, int(width), int(height))

    @property
    def shape(self) -> tuple[int, int]:
        """Image shape (height, width) in px."""
        return (self.height, self.width)

    @property
    def K(self) -> npt.NDArray[np.float64]:
        """3×3 intrinsic matrix [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def scaled(self, factor: float | Fraction) -> PinholeCamera:
        """The camera with the same field of view at a resolution ``factor`` times larger.

        Follows ``SPEC.md`` §1: f' = s·f and c' = s·(c + 0.5) − 0.5, i.e. pixel i of this camera
        sits at coordinate (i + 0.5)·s − 0.5 of the new one. ``factor`` may be a fraction 1/r.

        Parameters
        ----------
        factor : float or Fraction
            Scale s > 0; ``width·s`` and ``height·s`` must be integers (to within 1e−6).

        Raises
        ------
        InputError
            s ≤ 0, or the scaled image size is not a whole number of pixels.

        Examples
        --------
        >>> PinholeCamera(500.0, 500.0, 319.5, 239.5, 640, 480).scaled(2)
        PinholeCamera(fx=1000.0, fy=1000.0, cx=639.5, cy=479.5, width=1280, height=960)
        """
        s = float(factor)
        if not math.isfinite(s) or s <= 0:
            raise InputError(f"scale factor must be > 0, got {factor!r}")
        size = []
        for n in (self.width, self.height):
            m = n * s
            if abs(m - round(m)) > 1e-6 or round(m) < 1:
                raise InputError(
                    f"scaling {self.width}×{self.height} px by {factor} does not give a whole "
                    "number of pixels"
                )
            size.append(round(m))
        return PinholeCamera(
            self.fx * s,
            self.fy * s,
            s * (self.cx + 0.5) - 0.5,
            s * (self.cy + 0.5) - 0.5,
            size[0],
            size[1],
        )

    def rays(self) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """Per-pixel ray slopes (X/Z, Y/Z) at the pixel centres, each of shape (height, width)."""
        xs = (np.arange(self.width, dtype=np.float64) - self.cx) / self.fx
        ys = (np.arange(self.height, dtype=np.float64) - self.cy) / self.fy
        return np.broadcast_to(xs[None, :], self.shape), np.broadcast_to(ys[:, None], self.shape)
