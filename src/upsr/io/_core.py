"""Deprecated alias of :mod:`upsr.io.video` (the old ``upsr.io`` implementation module).

Kept only so that callers not yet moved (``upsr.apps.cli``, parts of ``upsr.apps.batch``) keep
working while they are edited in parallel; import :mod:`upsr.io` or :mod:`upsr.io.video`
instead. To be removed once nothing imports it.
"""

from upsr.io.video import (
    FORMATS,
    WRITE_FORMATS,
    VideoInfo,
    VideoWriter,
    check_output_path,
    intrinsics_path,
    iter_frames,
    probe,
    read_intrinsics,
    read_video,
    write_bytes_atomic,
    write_text_atomic,
    write_video,
)

__all__ = [
    "FORMATS",
    "WRITE_FORMATS",
    "VideoInfo",
    "VideoWriter",
    "check_output_path",
    "intrinsics_path",
    "iter_frames",
    "probe",
    "read_intrinsics",
    "read_video",
    "write_bytes_atomic",
    "write_text_atomic",
    "write_video",
]
