"""Wavefront OBJ reading for triangle-mesh sequences (e.g. the Samba sequence of Vlasic et al.).

Only geometry is read: ``v`` (vertex positions) and ``f`` (faces). Texture coordinates,
normals, groups, materials, lines and comments are ignored. Polygons are split into
triangles by fan triangulation; negative (relative) indices are resolved against the
vertices defined *before* the face, as the OBJ format prescribes.
"""

from __future__ import annotations

import os

import numpy as np
import numpy.typing as npt

from upsr.errors import InputError

__all__ = ["load_obj", "parse_obj"]


def load_obj(path: str | os.PathLike[str]) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.int32]]:
    """Read the vertices and triangles of a Wavefront OBJ file.

    Parameters
    ----------
    path : str or path-like
        The ``.obj`` file. Coordinates are returned as stored (the Samba meshes are in metres).

    Returns
    -------
    vertices : ndarray of float32, shape (V, 3)
        Vertex positions (x, y, z), in the file's unit.
    faces : ndarray of int32, shape (F, 3)
        Zero-based vertex indices of each triangle. Polygons with n > 3 corners become n − 2
        triangles (fan from their first corner).

    Raises
    ------
    InputError
        The file cannot be read, is not text, has no vertex, or has a malformed ``v``/``f``
        record (fewer than 3 coordinates or corners, non-numeric values, index 0 or out of
        range).
    """
    try:
        with open(path, "rb") as fh:
            data = fh.read()
    except OSError as exc:
        raise InputError(f"cannot read OBJ file {os.fspath(path)!r}: {exc}") from exc
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        text = data.decode("latin-1")
    if "\x00" in text:
        raise InputError(f"{os.fspath(path)!r} is not a text OBJ file")
    return parse_obj(text, name=os.fspath(path))


def parse_obj(
    text: str, *, name: str = "<obj>"
) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.int32]]:
    """Parse OBJ text; see :func:`load_obj` (``name`` is used in error messages)."""
    v_rows: list[list[str]] = []
    f_rows: list[list[str]] = []
    f_vcount: list[int] = []  # number of vertices defined before each face (negative indices)
    f_lineno: list[int] = []
    for lineno, raw in enumerate(text.splitlines(), start=1):
        if not raw or raw[0] not in "vf \t":
            continue  # fast skip of comments, vt/vn handled below, g/o/s/usemtl...
        parts = raw.split()
        if not parts:
            continue
        key = parts[0]
        if key == "v":
            if len(parts) < 4:
                raise InputError(f"{name}:{lineno}: vertex needs 3 coordinates: {raw.strip()!r}")
            v_rows.append(parts[1:4])
        elif key == "f":
            if len(parts) < 4:
                raise InputError(f"{name}:{lineno}: face needs at least 3 corners: {raw.strip()!r}")
            f_rows.append(parts[1:])
            f_vcount.append(len(v_rows))
            f_lineno.append(lineno)

    if not v_rows:
        raise InputError(f"{name}: no vertex ('v' record) found")
    try:
        vertices = np.array(v_rows, dtype=np.float64)
    except ValueError as exc:
        raise InputError(f"{name}: non-numeric vertex coordinate ({exc})") from None
    if not np.isfinite(vertices).all():
        raise InputError(f"{name}: vertex coordinates must be finite")
    n_vert = len(v_rows)

    if not f_rows:
        return vertices.astype(np.float32), np.zeros((0, 3), dtype=np.int32)

    counts = np.fromiter((len(r) for r in f_rows), dtype=np.int64, count=len(f_rows))
    tokens = [t for r in f_rows for t in r]
    if any("/" in t for t in tokens):
        tokens = [t.split("/", 1)[0] for t in tokens]
    try:
        idx = np.fromiter(map(int, tokens), dtype=np.int64, count=len(tokens))
    except (ValueError, OverflowError):
        bad = next(i for i, r in enumerate(f_rows) if not _all_int(r))
        raise InputError(
            f"{name}:{f_lineno[bad]}: non-integer vertex index in face {' '.join(f_rows[bad])!r}"
        ) from None

    defined = np.repeat(np.asarray(f_vcount, dtype=np.int64), counts)
    bad_mask = (idx == 0) | (idx > defined) | (idx < -defined)
    if bad_mask.any():
        corner = int(np.flatnonzero(bad_mask)[0])
        face = int(np.searchsorted(np.cumsum(counts), corner, side="right"))
        raise InputError(
            f"{name}:{f_lineno[face]}: vertex index {int(idx[corner])} out of range "
            f"(1..{int(defined[corner])} or -1..-{int(defined[corner])} at that point)"
        )
    idx = np.where(idx > 0, idx - 1, idx + defined)

    if (counts == 3).all():
        faces = idx.reshape(-1, 3)
    else:
        # Fan triangulation: corners (0, k, k + 1) for k = 1 .. n - 2 of each polygon.
        starts = np.concatenate(([0], np.cumsum(counts)[:-1]))
        n_tri = counts - 2
        tri_start = np.repeat(starts, n_tri)
        k = np.arange(int(n_tri.sum())) - np.repeat(np.cumsum(n_tri) - n_tri, n_tri) + 1
        faces = np.stack([idx[tri_start], idx[tri_start + k], idx[tri_start + k + 1]], axis=1)
    if n_vert > np.iinfo(np.int32).max:
        raise InputError(f"{name}: too many vertices ({n_vert}) for int32 indices")
    return vertices.astype(np.float32), np.ascontiguousarray(faces, dtype=np.int32)


def _all_int(tokens: list[str]) -> bool:
    try:
        for t in tokens:
            int(t.split("/", 1)[0])
    except ValueError:
        return False
    return True
