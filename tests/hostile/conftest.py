"""Shared helpers of the hostile-input tests: crafted files and one-line error checks."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np
import pytest

from upsr.errors import InputError


def assert_one_line(exc: pytest.ExceptionInfo[InputError], limit: int = 200) -> str:
    """The message of an InputError, checked to be one line of at most ``limit`` characters."""
    msg = str(exc.value)
    assert "\n" not in msg and len(msg) <= limit, (len(msg), msg[:300])
    return msg


def png_bomb(path: Path, w: int, h: int) -> Path:
    """A valid 16-bit grayscale PNG of w×h zeros: tiny on disk, huge decoded."""
    row = b"\x00" + b"\x00" * (2 * w)
    comp = zlib.compressobj(9)
    data = b"".join(comp.compress(row) for _ in range(h)) + comp.flush()

    def chunk(kind: bytes, body: bytes) -> bytes:
        return (
            struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))
        )

    ihdr = struct.pack(">IIBBBBB", w, h, 16, 0, 0, 0, 0)
    path.write_bytes(
        b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", data) + chunk(b"IEND", b"")
    )
    return path


def npy_header_bytes(shape: tuple[int, ...], descr: str = "<f4", fortran: bool = False) -> bytes:
    """A .npy v1.0 header declaring ``shape`` (no data follows)."""
    d = f"{{'descr': '{descr}', 'fortran_order': {fortran}, 'shape': {tuple(shape)}, }}"
    pad = 64 - (10 + len(d) + 1) % 64
    text = (d + " " * pad + "\n").encode("latin1")
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(text)) + text


@pytest.fixture
def small_video() -> np.ndarray:
    """A (3, 8, 6) float32 depth video in mm."""
    return np.full((3, 8, 6), 1000.0, np.float32)
