"""The data of the paper's experiments: Middlebury "Art" depth and rendered Samba sequences.

* :func:`load_middlebury_art` reads ``<data>/middlebury/art/disp1.png`` (2005 Middlebury
  stereo data, third size) and converts disparity v to depth with ``SPEC.md`` §5:
  depth mm = 3740 · 160 / (v + 200), v = 0 unknown (depth 0).
* :func:`render_samba` renders ``<data>/samba/mesh_XXXX.obj`` (Vlasic et al. 2008; metres,
  Y up) with one fixed pinhole camera at a high resolution (ground truth) and at lower
  resolutions with the *same* field of view (:meth:`PinholeCamera.scaled`, the pixel geometry
  of ``SPEC.md`` §1: low-res pixels are point samples at their centres), as
  ``benchmarks/samba_eval.py`` does. An optional lateral drift (a translation along the
  camera's x axis that grows by a fixed amount per frame) turns the dancer into the paper's
  "laterally moving person" (§7.5). Renders can be cached in a folder.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from upsr.errors import InputError
from upsr.research.experiments.common import Logger, null_logger
from upsr.research.synth.mesh import load_obj
from upsr.research.synth.render import (
    PinholeCamera,
    fit_camera_to_bounds,
    mesh_bounds,
    render_depth,
    samba_camera_and_pose,
)

__all__ = [
    "ART_BASELINE_MM",
    "ART_DISPARITY_OFFSET",
    "ART_FOCAL_PX",
    "SambaRender",
    "disparity_to_depth_mm",
    "load_middlebury_art",
    "render_samba",
    "samba_mesh_paths",
]

#: Conversion of the third-size Art disparities to depth (``SPEC.md`` §5).
ART_FOCAL_PX = 3740.0
ART_BASELINE_MM = 160.0
ART_DISPARITY_OFFSET = 200.0

#: Bump when the rendering changes in a way that invalidates cached renders.
RENDER_VERSION = 1


def disparity_to_depth_mm(disparity: np.ndarray) -> np.ndarray:
    """Middlebury Art disparity v → depth (mm) = 3740·160 / (v + 200); v = 0 → 0 (unknown)."""
    v = np.asarray(disparity, dtype=np.float64)
    depth = np.where(v > 0, ART_FOCAL_PX * ART_BASELINE_MM / (v + ART_DISPARITY_OFFSET), 0.0)
    return depth.astype(np.float32)


def load_middlebury_art(data: str | os.PathLike[str]) -> np.ndarray:
    """Depth (mm, float32, 0 = unknown) of ``<data>/middlebury/art/disp1.png``.

    Raises
    ------
    InputError
        The file is missing, unreadable, or not a single-channel image.
    """
    path = Path(data) / "middlebury" / "art" / "disp1.png"
    if not path.is_file():
        raise InputError(f"missing Middlebury disparity {path} (check --data)")
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise InputError(f"{path}: not a readable image")
    if img.ndim == 3:
        if not np.all(img == img[..., :1]):
            raise InputError(f"{path}: expected a grey (single-channel) disparity image")
        img = img[..., 0]
    depth = disparity_to_depth_mm(img)
    if not (depth > 0).any():
        raise InputError(f"{path}: no valid disparity")
    return depth


def samba_mesh_paths(
    data: str | os.PathLike[str], start: int, count: int, step: int = 1
) -> list[Path]:
    """``<data>/samba/mesh_XXXX.obj`` for XXXX = start, start + step, … (``count`` files).

    Raises
    ------
    InputError
        A file is missing.
    """
    folder = Path(data) / "samba"
    paths = [folder / f"mesh_{start + k * step:04d}.obj" for k in range(count)]
    for p in paths:
        if not p.is_file():
            raise InputError(
                f"missing Samba mesh {p} (check --data; {count} meshes from {start} "
                f"in steps of {step} are needed)"
            )
    return paths


@dataclass(frozen=True, eq=False)
class SambaRender:
    """A rendered mesh sequence.

    Attributes
    ----------
    truth : ndarray float32 (T, H, W)
        Depth (mm) at the high resolution, 0 = no surface.
    lowres : dict of int to ndarray float32 (T, H/r, W/r)
        Clean renders with the same field of view for each factor r.
    camera : PinholeCamera
        The high-res camera.
    world_to_camera : ndarray (4, 4)
        The fixed pose (metres).
    meshes : list of str
        Mesh file names, in order.
    """

    truth: np.ndarray
    lowres: dict[int, np.ndarray]
    camera: PinholeCamera
    world_to_camera: np.ndarray
    meshes: list[str]


def _cache_key(paths: Sequence[Path], params: dict[str, object]) -> str:
    files = [[p.name, p.stat().st_size, int(p.stat().st_mtime)] for p in paths]
    blob = json.dumps({"v": RENDER_VERSION, "files": files, **params}, sort_keys=True)
    return hashlib.sha1(blob.encode()).hexdigest()[:16]


def render_samba(
    paths: Sequence[Path],
    *,
    width: int,
    height: int,
    scales: Sequence[int] = (1,),
    fov_x_deg: float = 60.0,
    lateral_mm_per_frame: float = 0.0,
    background_mm: float | None = None,
    bounds_m: tuple[Sequence[float], Sequence[float]] | None = None,
    cache_dir: str | os.PathLike[str] | None = None,
    log: Logger = null_logger,
) -> SambaRender:
    """Render a mesh sequence with one fixed camera at several resolutions.

    The camera looks at the dancer from the front (:func:`samba_camera_and_pose`) and is
    fitted to the bounds of the rendered meshes (including the drift), so that the sequence
    fills the image. Frame k is translated by ``k · lateral_mm_per_frame`` along the camera's
    x axis (positive: to the right in the image).

    Parameters
    ----------
    paths : sequence of Path
        OBJ files in temporal order (vertices in metres).
    width, height : int
        High-res size (px); must be divisible by every factor in ``scales``.
    scales : sequence of int
        Factors r: a render at (width/r, height/r) with the same field of view is made for
        each (r = 1 is the truth itself).
    fov_x_deg : float
        Horizontal field of view (degrees).
    lateral_mm_per_frame : float
        Lateral drift per frame (mm).
    background_mm : float or None
        Depth (mm) of a wall behind the dancer filling the empty pixels; ``None``: 0 (no
        return).
    bounds_m : ((x, y, z), (x, y, z)) or None
        World box (m) the camera is fitted to; ``None``: the bounds of the rendered meshes.
    cache_dir : path-like, optional
        Folder for a cache of the renders (``samba_<key>.npz``).
    log : callable
        Progress messages.

    Returns
    -------
    SambaRender
    """
    if not paths:
        raise InputError("render_samba: no mesh given")
    for r in scales:
        if width % r or height % r:
            raise InputError(f"{width}x{height} is not divisible by r = {r}")
    factors = sorted({int(r) for r in scales})
    params = {
        "width": width,
        "height": height,
        "scales": factors,
        "fov": fov_x_deg,
        "drift": lateral_mm_per_frame,
    }
    if background_mm is not None:
        params["background_mm"] = float(background_mm)
    if bounds_m is not None:
        params["bounds_m"] = [list(map(float, b)) for b in bounds_m]
    cache = None
    if cache_dir is not None:
        cache = Path(cache_dir) / f"samba_{_cache_key(paths, params)}.npz"
    lo, hi = mesh_bounds(paths) if bounds_m is None else map(np.asarray, bounds_m)
    cam, pose = samba_camera_and_pose(
        width=width, height=height, fov_x_deg=fov_x_deg, bounds_m=(lo, hi)
    )
    shift = np.zeros(3)
    if lateral_mm_per_frame:
        # the camera's x axis in world coordinates (first row of the rotation); refit the
        # camera to the bounds swept by the drifting meshes (same viewing direction)
        shift = pose[0, :3] * (lateral_mm_per_frame / 1000.0)
        total = shift * (len(paths) - 1)
        lo, hi = lo + np.minimum(total, 0.0), hi + np.maximum(total, 0.0)
        view = pose[2, :3]
        cam, pose = fit_camera_to_bounds(
            lo, hi, width=width, height=height, fov_x_deg=fov_x_deg, view_dir=view, margin=0.05
        )
    if cache is not None and cache.is_file():
        with np.load(cache) as z:
            log(f"using cached renders {cache}")
            lowres = {r: z[f"lowres_{r}"] for r in factors}
            return SambaRender(z["truth"], lowres, cam, pose, [p.name for p in paths])
    cams = {r: cam.scaled(1 / r) for r in factors}
    log(
        f"rendering {len(paths)} meshes ({paths[0].name} ...) at "
        + ", ".join(f"{c.width}x{c.height}" for c in [cam, *(cams[r] for r in cams if r != 1)])
    )
    truth = np.empty((len(paths), cam.height, cam.width), np.float32)
    lowres = {r: np.empty((len(paths), c.height, c.width), np.float32) for r, c in cams.items()}
    for k, path in enumerate(paths):
        verts, faces = load_obj(path)
        verts = verts + k * shift
        truth[k] = render_depth(
            verts, faces, cam, world_to_camera=pose, background_mm=background_mm
        )
        for r, c in cams.items():
            lowres[r][k] = (
                truth[k]
                if r == 1
                else render_depth(
                    verts, faces, c, world_to_camera=pose, background_mm=background_mm
                )
            )
    if not (truth > 0).any():
        raise InputError("the rendered meshes are not visible (no depth in the renders)")
    if cache is not None:
        cache.parent.mkdir(parents=True, exist_ok=True)
        tmp = cache.with_suffix(".tmp.npz")
        np.savez(tmp, truth=truth, **{f"lowres_{r}": v for r, v in lowres.items()})
        os.replace(tmp, cache)
    return SambaRender(truth, lowres, cam, pose, [p.name for p in paths])
