"""A small animated-GIF writer (NumPy + numba, no Pillow): streamed, atomic, per-frame palettes.

Each frame gets its own 256-colour palette (a GIF local colour table): the exact colours when a
frame has at most 256, else the 256 most frequent colours at 5 bits per channel (each one the
mean of its pixels) with every other colour mapped to the nearest of them. Colour-mapped depth
pictures (a few hundred distinct colours) come out nearly exact. LZW compression follows the
GIF89a specification (variable code width, clear code when the 4096-entry table is full).
"""

from __future__ import annotations

import contextlib
import os
import struct
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
from numba import njit

from upsr._atomic import AtomicWriter
from upsr.errors import InputError

__all__ = ["GifWriter", "lzw_encode", "quantize"]


@njit(cache=True)
def _lzw(indices: np.ndarray, out: np.ndarray) -> int:  # pragma: no cover - numba
    clear, eoi = 256, 257
    table = np.full(4096 * 256, -1, np.int16)
    gen = np.zeros(4096 * 256, np.int32)
    g = 1
    code_size = 9
    next_code = 258
    acc = 0
    nbits = 0
    pos = 0
    # clear code first
    acc |= clear << nbits
    nbits += code_size
    while nbits >= 8:
        out[pos] = acc & 0xFF
        pos += 1
        acc >>= 8
        nbits -= 8
    prefix = np.int64(indices[0])
    for i in range(1, indices.size):
        k = np.int64(indices[i])
        key = prefix * 256 + k
        if gen[key] == g:
            prefix = table[key]
            continue
        acc |= prefix << nbits
        nbits += code_size
        while nbits >= 8:
            out[pos] = acc & 0xFF
            pos += 1
            acc >>= 8
            nbits -= 8
        table[key] = next_code
        gen[key] = g
        next_code += 1
        if next_code > (1 << code_size) and code_size < 12:
            code_size += 1
        if next_code == 4096:
            acc |= clear << nbits
            nbits += code_size
            while nbits >= 8:
                out[pos] = acc & 0xFF
                pos += 1
                acc >>= 8
                nbits -= 8
            g += 1
            code_size = 9
            next_code = 258
        prefix = k
    acc |= prefix << nbits
    nbits += code_size
    # the decoder adds an entry after the last code: it may widen the code for EOI
    if next_code == (1 << code_size) and code_size < 12:
        code_size += 1
    acc |= eoi << nbits
    nbits += code_size
    while nbits > 0:
        out[pos] = acc & 0xFF
        pos += 1
        acc >>= 8
        nbits -= 8
    return pos


def lzw_encode(indices: npt.ArrayLike) -> bytes:
    """GIF LZW code stream (minimum code size 8) of palette indices, without sub-blocks."""
    idx = np.ascontiguousarray(np.asarray(indices, dtype=np.uint8).reshape(-1))
    if idx.size == 0:
        raise InputError("cannot encode an empty image")
    out = np.empty(idx.size * 2 + 16, np.uint8)
    n = _lzw(idx, out)
    return out[:n].tobytes()


def quantize(image_bgr: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Palette (256, 3) RGB uint8 and indices (h, w) uint8 of a BGR uint8 image."""
    img = np.asarray(image_bgr)
    if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] != 3 or img.size == 0:
        raise InputError(f"expected a BGR uint8 image (h, w, 3), got {img.dtype} {img.shape}")
    rgb = img[..., ::-1].reshape(-1, 3)
    packed = (rgb[:, 0].astype(np.int64) << 16) | (rgb[:, 1].astype(np.int64) << 8) | rgb[:, 2]
    colours, inverse = np.unique(packed, return_inverse=True)
    palette = np.zeros((256, 3), np.uint8)
    if colours.size <= 256:
        palette[: colours.size, 0] = colours >> 16
        palette[: colours.size, 1] = (colours >> 8) & 0xFF
        palette[: colours.size, 2] = colours & 0xFF
        return palette, inverse.reshape(img.shape[:2]).astype(np.uint8)
    r5, g5, b5 = (rgb[:, c].astype(np.int64) >> 3 for c in range(3))
    q = (r5 << 10) | (g5 << 5) | b5
    counts = np.bincount(q, minlength=1 << 15)
    top = np.argsort(counts, kind="stable")[::-1][:256]
    top = top[counts[top] > 0]
    sums = np.stack(
        [np.bincount(q, weights=rgb[:, c], minlength=1 << 15) for c in range(3)], axis=1
    )
    centres = sums[top] / counts[top, None]
    palette[: len(top)] = np.clip(np.rint(centres), 0, 255).astype(np.uint8)
    used = np.nonzero(counts)[0]
    cols = np.stack([(used >> 10) & 31, (used >> 5) & 31, used & 31], axis=1) * 8.0 + 4.0
    pal = palette[: len(top)].astype(np.float64)
    d2 = (cols**2).sum(1)[:, None] - 2.0 * cols @ pal.T + (pal**2).sum(1)[None, :]
    lut = np.zeros(1 << 15, np.uint8)
    lut[used] = np.argmin(d2, axis=1).astype(np.uint8)
    lut[top] = np.arange(len(top), dtype=np.uint8)
    return palette, lut[q].reshape(img.shape[:2])


class GifWriter(AtomicWriter):
    """Write an animated GIF frame by frame; the file appears only when :meth:`close` succeeds.

    Parameters
    ----------
    path : path-like
        Destination ``.gif`` (parent folders are created).
    fps : float
        Frames per second (GIF delays are whole centiseconds).
    loop : int
        Number of repetitions, 0 = forever.
    """

    def __init__(self, path: str | os.PathLike[str], fps: float = 5.0, loop: int = 0) -> None:
        if not (np.isfinite(fps) and fps > 0):
            raise InputError(f"fps must be > 0, got {fps!r}")
        self.path = Path(path)
        self._delay = max(1, round(100.0 / fps))
        self._loop = int(loop)
        self._size: tuple[int, int] | None = None
        self._fh: Any = None
        self._temp: Path | None = None
        self.frames_written = 0

    def _start(self, h: int, w: int) -> None:
        if h > 65535 or w > 65535:
            raise InputError(f"a GIF frame is at most 65535x65535 px, got {w}x{h}")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._temp = self.path.with_name(f".{self.path.name}.{os.getpid()}.part")
        self._fh = open(self._temp, "wb")  # closed in close() / abort()
        self._fh.write(b"GIF89a" + struct.pack("<HHBBB", w, h, 0, 0, 0))
        # NETSCAPE2.0 looping extension
        self._fh.write(b"\x21\xff\x0bNETSCAPE2.0\x03\x01" + struct.pack("<H", self._loop) + b"\0")
        self._size = (h, w)

    def write(self, image_bgr: npt.ArrayLike) -> None:
        """Append one BGR uint8 frame (all frames must have the first one's size)."""
        img = np.asarray(image_bgr)
        if self._size is None:
            if img.ndim != 3:
                raise InputError(f"expected a BGR image (h, w, 3), got shape {img.shape}")
            self._start(img.shape[0], img.shape[1])
        elif img.shape[:2] != self._size:
            raise InputError(f"GIF frame of {img.shape[:2]} differs from the first {self._size}")
        palette, idx = quantize(img)
        h, w = idx.shape
        f = self._fh
        f.write(b"\x21\xf9\x04\x04" + struct.pack("<H", self._delay) + b"\x00\x00")
        f.write(b"\x2c" + struct.pack("<HHHH", 0, 0, w, h) + b"\x87")  # local table, 256 colours
        f.write(palette.tobytes())
        data = lzw_encode(idx)
        f.write(b"\x08")
        for i in range(0, len(data), 255):
            block = data[i : i + 255]
            f.write(bytes([len(block)]) + block)
        f.write(b"\x00")
        self.frames_written += 1

    def close(self) -> Path:
        """Finish the file and move it into place. Returns its path."""
        if self._fh is None:
            raise InputError(f"{self.path}: no frames written")
        try:
            self._fh.write(b"\x3b")
            self._fh.flush()
            os.fsync(self._fh.fileno())
            self._fh.close()
            self._fh = None
            assert self._temp is not None
            os.replace(self._temp, self.path)
        except BaseException:
            self.abort()
            raise
        return self.path

    def abort(self) -> None:
        """Discard the partial file."""
        if self._fh is not None:
            with contextlib.suppress(OSError):
                self._fh.close()
            self._fh = None
        if self._temp is not None:
            with contextlib.suppress(OSError):
                self._temp.unlink()
