"""Animations streamed frame by frame and published atomically: GIF (Pillow) and MP4 (H.264).

:class:`Mp4Writer` pipes the frames to the ffmpeg of ``imageio-ffmpeg`` (libx264, yuv420p,
``+faststart`` so that browsers start playing before the download ends); odd frame sizes are
padded with white to even ones, as yuv420p needs.


Each frame gets its own adaptive 256-colour palette (a GIF local colour table, median cut) and
is mapped onto it with Floyd–Steinberg dithering; a frame with at most 256 colours keeps them
exactly, undithered. Frames are encoded and written
to a hidden temporary file as they arrive (constant memory); the GIF appears at its path only
when :meth:`GifWriter.close` succeeds.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path
from typing import IO, Any

import numpy as np
import numpy.typing as npt

from upsr._atomic import AtomicWriter, new_temp_file, remove
from upsr.errors import InputError
from upsr.viz._optional import require

__all__ = ["GifWriter", "Mp4Writer", "to_palette_image"]


def _pil() -> tuple[Any, Any]:
    image = require("PIL.Image", "writing GIF files")
    gif = require("PIL.GifImagePlugin", "writing GIF files")
    return image, gif


def to_palette_image(image_bgr: npt.ArrayLike) -> Any:
    """A BGR uint8 image as a Pillow ``P`` image: adaptive 256-colour palette, dithered.

    Parameters
    ----------
    image_bgr : array_like (h, w, 3) uint8
        Blue-green-red picture (OpenCV order).

    Returns
    -------
    PIL.Image.Image
        Mode ``"P"``; at most 256 palette entries.
    """
    img = np.asarray(image_bgr)
    if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] != 3 or img.size == 0:
        raise InputError(f"expected a BGR uint8 image (h, w, 3), got {img.dtype} {img.shape}")
    image, _ = _pil()
    rgb = image.fromarray(np.ascontiguousarray(img[..., ::-1]), "RGB")
    palette = rgb.quantize(256, method=image.Quantize.MEDIANCUT, dither=image.Dither.NONE)
    if rgb.getcolors(256) is not None:  # few colours: the palette holds them all, exactly
        return palette
    return rgb.quantize(palette=palette, dither=image.Dither.FLOYDSTEINBERG)


class _TempFileWriter(AtomicWriter):
    """A writer that fills a hidden temporary file and publishes it on :meth:`close`.

    Subclasses implement ``_finish()`` (complete the file; raise on failure) and
    ``_release()`` (drop their handle without finishing).
    """

    path: Path
    _temp: Path | None = None

    def _finish(self) -> None:  # pragma: no cover - overridden
        raise NotImplementedError

    def _release(self) -> None:  # pragma: no cover - overridden
        raise NotImplementedError

    def _started(self) -> bool:  # pragma: no cover - overridden
        raise NotImplementedError

    def close(self) -> Path:
        """Finish the file and move it into place. Returns its path."""
        if not self._started():
            raise InputError(f"{self.path}: no frames written")
        try:
            self._finish()
            assert self._temp is not None
            os.replace(self._temp, self.path)
            self._temp = None
        except BaseException:
            self.abort()
            raise
        return self.path

    def abort(self) -> None:
        """Discard the partial file."""
        self._release()
        if self._temp is not None:
            remove(self._temp)
            self._temp = None


class GifWriter(_TempFileWriter):
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
        self._duration_ms = 10 * max(1, round(100.0 / fps))
        self._loop = int(loop)
        self._size: tuple[int, int] | None = None
        self._fh: IO[bytes] | None = None
        self._temp: Path | None = None
        self.frames_written = 0

    def write(self, image_bgr: npt.ArrayLike) -> None:
        """Append one BGR uint8 frame (all frames must have the first one's size)."""
        img = np.asarray(image_bgr)
        if img.ndim != 3:
            raise InputError(f"expected a BGR image (h, w, 3), got shape {img.shape}")
        if self._size is not None and img.shape[:2] != self._size:
            raise InputError(f"GIF frame of {img.shape[:2]} differs from the first {self._size}")
        if img.shape[0] > 65535 or img.shape[1] > 65535:
            h, w = img.shape[:2]
            raise InputError(f"a GIF frame is at most 65535x65535 px, got {w}x{h}")
        frame = to_palette_image(img)
        _, gif = _pil()
        chunks: list[bytes] = []
        if self._fh is None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._temp, self._fh = new_temp_file(self.path, "part")
            self._size = img.shape[:2]
            header, _ = gif.getheader(frame, None, {"loop": self._loop, "duration": 1})
            chunks += header
        chunks += gif.getdata(frame, duration=self._duration_ms, include_color_table=True)
        self._fh.write(b"".join(chunks))
        self.frames_written += 1

    def _started(self) -> bool:
        return self._fh is not None

    def _finish(self) -> None:
        assert self._fh is not None
        self._fh.write(b";")  # GIF trailer
        self._fh.flush()
        os.fsync(self._fh.fileno())
        self._fh.close()
        self._fh = None

    def _release(self) -> None:
        if self._fh is not None:
            with contextlib.suppress(OSError):
                self._fh.close()
            self._fh = None


class Mp4Writer(_TempFileWriter):
    """Write an H.264 MP4 (yuv420p, faststart) frame by frame; it appears only on :meth:`close`.

    Parameters
    ----------
    path : path-like
        Destination ``.mp4`` (parent folders are created).
    fps : float
        Frames per second.
    crf : int
        libx264 constant rate factor (0 lossless … 51 worst; 18 is visually lossless).

    Notes
    -----
    Frames are BGR uint8 ``(h, w, 3)``; all take the first one's size (smaller ones are padded,
    larger ones cropped, with white). An odd width or height is padded by one pixel.
    """

    def __init__(self, path: str | os.PathLike[str], fps: float = 5.0, crf: int = 18) -> None:
        if not (np.isfinite(fps) and fps > 0):
            raise InputError(f"fps must be > 0, got {fps!r}")
        if not 0 <= int(crf) <= 51:
            raise InputError(f"crf must be in [0, 51], got {crf!r}")
        self.path = Path(path)
        self.fps = float(fps)
        self.crf = int(crf)
        self._gen: Any = None
        self._temp: Path | None = None
        self._size: tuple[int, int] | None = None
        self.frames_written = 0

    def _start(self, h: int, w: int) -> None:
        ffmpeg = require("imageio_ffmpeg", "writing MP4 files")
        self._size = (h + h % 2, w + w % 2)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._temp, fh = new_temp_file(self.path, "part.mp4")  # ffmpeg overwrites it
        fh.close()
        self._gen = ffmpeg.write_frames(
            str(self._temp),
            (self._size[1], self._size[0]),
            fps=self.fps,
            codec="libx264",
            pix_fmt_in="bgr24",
            pix_fmt_out="yuv420p",
            quality=None,
            macro_block_size=1,
            ffmpeg_log_level="error",
            output_params=["-crf", str(self.crf), "-movflags", "+faststart", "-f", "mp4"],
        )
        self._gen.send(None)

    def write(self, image_bgr: npt.ArrayLike) -> None:
        """Append one BGR uint8 frame."""
        img = np.asarray(image_bgr)
        if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] != 3 or img.size == 0:
            raise InputError(f"expected a BGR uint8 image (h, w, 3), got {img.dtype} {img.shape}")
        h, w = img.shape[:2]
        try:
            if self._gen is None:
                self._start(h, w)
            assert self._size is not None
            frame = np.full((*self._size, 3), 255, np.uint8)
            hh, ww = min(h, self._size[0]), min(w, self._size[1])
            frame[:hh, :ww] = img[:hh, :ww]
            self._gen.send(frame)
        except BaseException:
            self.abort()
            raise
        self.frames_written += 1

    def _started(self) -> bool:
        return self._gen is not None

    def _finish(self) -> None:
        gen, self._gen = self._gen, None
        gen.close()  # ffmpeg finishes the file (moov atom first) and exits
        assert self._temp is not None
        if not self._temp.is_file() or self._temp.stat().st_size == 0:
            raise OSError(f"{self.path}: ffmpeg wrote no MP4 data")

    def _release(self) -> None:
        """Stop ffmpeg."""
        if self._gen is not None:
            with contextlib.suppress(Exception):
                self._gen.close()
            self._gen = None
