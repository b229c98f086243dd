"""GIF (Pillow) and H.264 MP4 (imageio-ffmpeg) writers: read back, atomic, optional extra."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from upsr.errors import InputError
from upsr.viz.animation import GifWriter, Mp4Writer, to_palette_image
from upsr.viz.colormaps import colorize_depth
from upsr.viz.pictures import ComparisonWriter

Image = pytest.importorskip("PIL.Image")
imageio_ffmpeg = pytest.importorskip("imageio_ffmpeg")


def frames(t: int = 4, h: int = 30, w: int = 41) -> list[np.ndarray]:
    """Colour-mapped depth ramps (a few hundred colours) moving right, BGR uint8."""
    xx = np.arange(w, dtype=np.float64)[None, :].repeat(h, 0)
    return [colorize_depth(1000.0 + 40.0 * xx + 30.0 * k, 1000.0, 3000.0) for k in range(t)]


def gif_frames(path: Path) -> list[np.ndarray]:
    with Image.open(path) as im:
        out = []
        for k in range(im.n_frames):
            im.seek(k)
            out.append(np.asarray(im.convert("RGB"))[..., ::-1])
        return out


def test_gif_reads_back_with_pillow(tmp_path: Path) -> None:
    src = frames()
    rng = np.random.default_rng(0)
    noisy = np.clip(src[0].astype(int) + rng.integers(-40, 40, src[0].shape), 0, 255)
    src.append(noisy.astype(np.uint8))  # thousands of colours: adaptive palette + dithering
    with GifWriter(tmp_path / "sub" / "a.gif", fps=4) as g:
        for f in src:
            g.write(f)
    path = tmp_path / "sub" / "a.gif"
    with Image.open(path) as im:
        assert im.format == "GIF" and im.n_frames == 5 and im.size == (41, 30)
        assert im.info["loop"] == 0 and im.info["duration"] == 250
    got = gif_frames(path)
    for a, b in zip(got[:4], src[:4], strict=True):  # <= 256 colours: exact
        np.testing.assert_array_equal(a, b)
    err = np.abs(got[4].astype(int) - src[4].astype(int))
    assert err.mean() < 12  # dithered, close on average
    assert float(np.abs(got[4].astype(float).mean((0, 1)) - src[4].mean((0, 1))).max()) < 3
    assert sorted(p.name for p in path.parent.iterdir()) == ["a.gif"]  # no temporary left


def test_gif_writer_is_atomic_and_checks_input(tmp_path: Path) -> None:
    with pytest.raises(RuntimeError), GifWriter(tmp_path / "b.gif") as g:
        g.write(frames(1)[0])
        raise RuntimeError
    assert list(tmp_path.iterdir()) == []
    g = GifWriter(tmp_path / "c.gif")
    g.write(frames(1)[0])
    with pytest.raises(InputError, match="differs"):
        g.write(np.zeros((5, 5, 3), np.uint8))
    g.abort()
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(InputError, match="no frames"):
        GifWriter(tmp_path / "d.gif").close()
    with pytest.raises(InputError, match="fps"):
        GifWriter(tmp_path / "d.gif", fps=0)
    with pytest.raises(InputError, match="BGR"):
        to_palette_image(np.zeros((4, 4), np.uint8))


def test_mp4_is_h264_and_reads_back(tmp_path: Path) -> None:
    src = frames(t=6, h=31, w=41)  # odd sizes: padded to 42x32 for yuv420p
    path = tmp_path / "v.mp4"
    with Mp4Writer(path, fps=5) as w:
        for f in src:
            w.write(f)
    reader = imageio_ffmpeg.read_frames(str(path))
    meta = next(reader)
    n = sum(1 for _ in reader)
    assert meta["codec"] == "h264" and meta["pix_fmt"].startswith("yuv420p")
    assert meta["size"] == (42, 32) and n == 6 and meta["fps"] == pytest.approx(5.0)
    data = path.read_bytes()
    assert 0 <= data.find(b"moov") < data.find(b"mdat")  # faststart: index first
    cap = cv2.VideoCapture(str(path))
    ok, first = cap.read()
    assert ok and first.shape == (32, 42, 3)
    assert np.abs(first[:31, :41].astype(int) - src[0]).mean() < 8  # crf 18, chroma 4:2:0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["v.mp4"]


def test_mp4_writer_is_atomic(tmp_path: Path) -> None:
    with pytest.raises(RuntimeError), Mp4Writer(tmp_path / "v.mp4") as w:
        w.write(frames(1)[0])
        raise RuntimeError
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(InputError, match="no frames"):
        Mp4Writer(tmp_path / "v.mp4").close()
    with pytest.raises(InputError, match="BGR"):
        Mp4Writer(tmp_path / "v.mp4").write(np.zeros((4, 4), np.float32))
    assert list(tmp_path.iterdir()) == []


def test_comparison_writer_kinds(tmp_path: Path) -> None:
    for name in ("a.gif", "a.mp4"):
        with ComparisonWriter(tmp_path / name, fps=4) as w:
            for f in frames(3):
                w.write(f)
    assert len(gif_frames(tmp_path / "a.gif")) == 3
    cap = cv2.VideoCapture(str(tmp_path / "a.mp4"))
    n = 0
    while cap.read()[0]:
        n += 1
    assert n == 3
    with pytest.raises(RuntimeError), ComparisonWriter(tmp_path / "b.mp4") as w:
        w.write(frames(1)[0])
        raise RuntimeError
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.gif", "a.mp4"]


_BLOCK = """
import sys
class Block:
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in ("PIL", "matplotlib", "imageio", "imageio_ffmpeg"):
            raise ImportError(f"blocked {name}")
sys.meta_path.insert(0, Block())
"""


def test_without_the_viz_extra(tmp_path: Path) -> None:
    """The core install runs `upsr run`; GIF / MP4 / figures say which extra is missing."""
    v = np.stack([np.full((8, 10), 1500.0 + 10 * k, np.float32) for k in range(3)])
    np.save(tmp_path / "in.npy", v)
    code = (
        _BLOCK
        + f"""
import numpy as np
from upsr.apps.cli.main import main
from upsr.errors import InputError
assert main(["run", {str(tmp_path / "in.npy")!r}, "-o", {str(tmp_path / "o.npy")!r},
             "-r", "2", "-n", "3", "--quiet"]) == 0
from upsr.viz.animation import GifWriter, Mp4Writer
from upsr.viz.figures import Series, line_plot
img = np.zeros((4, 4, 3), np.uint8)
for make in (lambda: GifWriter({str(tmp_path / "a.gif")!r}).write(img),
             lambda: Mp4Writer({str(tmp_path / "a.mp4")!r}).write(img),
             lambda: line_plot([Series([1, 2], [1, 2])]).render("png")):
    try:
        make()
    except InputError as e:
        assert "pip install 'upsr[viz]'" in str(e), e
        print(e)
    else:
        raise AssertionError("no InputError")
assert not any(m.split(".")[0] in ("PIL", "matplotlib", "imageio_ffmpeg") for m in sys.modules)
"""
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    assert "'pillow'" in res.stdout and "'imageio-ffmpeg'" in res.stdout
    assert "'matplotlib'" in res.stdout
    assert np.load(tmp_path / "o.npy").shape == (3, 16, 20)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.npy", "o.npy"]
