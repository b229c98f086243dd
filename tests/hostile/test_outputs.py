"""Outputs: never onto an input or a device, exclusive publication, legal long names, stale
temporaries of dead writers removed, sidecars published with the video or not at all."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from upsr import io
from upsr._atomic import publish, temp_name
from upsr.errors import InputError

from .conftest import assert_one_line


def _video() -> np.ndarray:
    return np.full((2, 8, 6), 1000.0, np.float32)


def test_output_inside_input_folder_refused_even_with_overwrite(tmp_path: Path) -> None:
    tifs = tmp_path / "tifs"
    tifs.mkdir()
    for i in range(3):
        np.save(tifs / f"f{i:03d}.npy", _video())
    for out in (tifs / "f001.npy", tifs / "new.npy", tifs / "sub" / "x.npy"):
        with pytest.raises(InputError, match="input") as e:
            io.check_output_path([tifs], out, overwrite=True)
        assert_one_line(e)
    io.check_output_path([tifs], tmp_path / "out.npy", overwrite=True)


def test_output_symlink_loop(tmp_path: Path) -> None:
    a, b = tmp_path / "a.npy", tmp_path / "b.npy"
    a.symlink_to(b)
    b.symlink_to(a)
    with pytest.raises(InputError, match="loop") as e:
        io.check_output_path([], a, overwrite=True)
    assert_one_line(e)


def test_character_device_output_never_replaced(tmp_path: Path) -> None:
    link = tmp_path / "null.npy"
    link.symlink_to("/dev/null")
    for out in (Path("/dev/null"), link):
        with pytest.raises(InputError, match="character device") as e:
            io.check_output_path([], out, overwrite=True, fmt="npy")
        assert_one_line(e)
    fifo = tmp_path / "p.npy"
    os.mkfifo(fifo)
    with pytest.raises(InputError, match="FIFO"):
        io.write_video(fifo, _video(), overwrite=True)
    assert Path("/dev/null").is_char_device()


def test_legal_249_character_output_name(tmp_path: Path) -> None:
    out = tmp_path / ("x" * 245 + ".npy")
    assert len(out.name) == 249
    assert len(temp_name(out, "part").name.encode()) <= 255
    io.write_video(out, _video())
    np.testing.assert_array_equal(io.read_video(out), _video())
    png = tmp_path / ("y" * 249)
    io.write_video(png, _video())
    assert len(os.listdir(tmp_path)) == 2


def test_publish_does_not_replace(tmp_path: Path) -> None:
    for folder in (False, True):
        dest = tmp_path / f"d{folder}"
        tmp1, tmp2 = tmp_path / f".a{folder}", tmp_path / f".b{folder}"
        for t in (tmp1, tmp2):
            if folder:
                t.mkdir()
                (t / "000000.png").write_bytes(b"x")
            else:
                t.write_bytes(b"x")
        publish(tmp1, dest, replace=False)
        with pytest.raises(FileExistsError):
            publish(tmp2, dest, replace=False)
        assert os.path.lexists(tmp2)


def test_two_writers_finishing_the_same_output_one_fails(tmp_path: Path) -> None:
    out = tmp_path / "o.npy"
    w1 = io.VideoWriter(out, n_frames=2)
    w2 = io.VideoWriter(out, n_frames=2)  # both checked before either exists
    for w in (w1, w2):
        for f in _video():
            w.write(f)
    w1.close()
    with pytest.raises(InputError, match="already exists"):
        w2.close()
    np.testing.assert_array_equal(io.read_video(out), _video())
    assert sorted(os.listdir(tmp_path)) == ["o.npy"]


def test_stale_part_files_of_dead_processes_removed(tmp_path: Path) -> None:
    out = tmp_path / "o.npy"
    code = (
        "import os, sys\nfrom upsr import io\nimport numpy as np\n"
        "w = io.VideoWriter(sys.argv[1]); w.write(np.ones((4, 4), np.float32))\n"
        "w2 = io.VideoWriter(sys.argv[2]); w2.write(np.ones((4, 4), np.float32))\n"
        "os._exit(0)  # like SIGKILL: no cleanup\n"
    )
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    subprocess.run(
        [sys.executable, "-c", code, str(out), str(tmp_path / "frames")],
        check=True,
        timeout=60,
        env=env,
    )
    stale = [p for p in os.listdir(tmp_path) if p.startswith(".")]
    assert len(stale) == 2, stale
    live = temp_name(out, "part")  # ours (a live PID): kept
    live.write_bytes(b"")
    io.write_video(out, _video())
    io.write_video(tmp_path / "frames", _video())
    assert sorted(os.listdir(tmp_path)) == sorted([live.name, "frames", "o.npy"])


def test_stale_temporaries_of_a_folder_removed(tmp_path: Path) -> None:
    """``remove_stale_in`` (what ``upsr batch`` runs in its chunk folders after Ctrl-C killed
    its workers): the temporaries of every destination of dead writers go, a live one's and
    the complete files stay."""
    from upsr._atomic import remove_stale_in

    code = (
        "import os, sys\nfrom upsr import io\nimport numpy as np\n"
        "ws = [io.VideoWriter(p, fmt='npy') for p in sys.argv[1:]]\n"
        "for w in ws:\n"
        "    w.write(np.ones((4, 4), np.float32))\n"
        "os._exit(0)  # like SIGKILL: no cleanup\n"
    )
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    names = ("chunk_0_4.npy", "chunk_4_8.npy")
    subprocess.run([sys.executable, "-c", code, *(str(tmp_path / n) for n in names)],
                   check=True, timeout=60, env=env)  # fmt: skip
    (tmp_path / "done.npy").write_bytes(b"x")
    live = temp_name(tmp_path / "chunk_8_12.npy", "part")  # ours (a live PID): kept
    live.write_bytes(b"")
    assert len(os.listdir(tmp_path)) == 4
    assert len(remove_stale_in(tmp_path)) == 2
    assert sorted(os.listdir(tmp_path)) == sorted([live.name, "done.npy"])
    assert remove_stale_in(tmp_path / "missing") == []


def test_sidecar_failure_leaves_no_complete_output(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    out = tmp_path / "o.npy"
    side = io.intrinsics_path(out)
    real_replace = os.replace

    def failing_replace(src, dst):  # the sidecar cannot be published (disk full, …)
        if Path(dst) == side:
            raise OSError(28, "No space left on device")
        return real_replace(src, dst)

    monkeypatch.setattr(os, "replace", failing_replace)
    with pytest.raises(OSError), io.VideoWriter(out, n_frames=2) as w:
        w.add_sidecar(side, "{}")
        for f in _video():
            w.write(f)
    assert os.listdir(tmp_path) == []
    monkeypatch.undo()
    with io.VideoWriter(out, n_frames=2) as w:
        w.add_sidecar(side, '{"a": 1}\n')
        for f in _video():
            w.write(f)
    assert sorted(os.listdir(tmp_path)) == ["o.npy", "o.npy.intrinsics.json"]
    assert side.read_text() == '{"a": 1}\n'
