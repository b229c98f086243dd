"""Line plots drawn with matplotlib: PNG and SVG files, labels with units and symbols."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from upsr.errors import InputError
from upsr.viz.figures import PALETTE, Series, line_plot, write_figure

Image = pytest.importorskip("PIL.Image")
pytest.importorskip("matplotlib")


def _svg_texts(path: Path) -> list[str]:
    return re.findall(r"<text[^>]*>([^<]+)</text>", path.read_text(encoding="utf-8"))


def test_png_and_svg_with_labels(tmp_path: Path) -> None:
    x = np.arange(1, 11, dtype=float)
    plot = line_plot(
        [
            Series(x, 450.0 / x, "Cramér–Rao bound σ²/(2N)", PALETTE[2], "dashed"),
            Series(x, 600.0 / x, "theory", PALETTE[0], "solid", 3),
            Series(x, np.r_[0.0, 610.0 / x[1:]], "Monte-Carlo", "black", "markers"),
            Series(x, 700.0 / x, "", PALETTE[1], "line+markers"),  # not in the legend
        ],
        title="Median of N samples, σ = 30 mm",
        xlabel="number of frames N",
        ylabel="variance [mm²]",
        size=(640, 400),
        log_y=True,
        legend="upper right",
    )
    png, svg = write_figure(tmp_path / "out" / "fig.png", plot)
    assert (png.name, svg.name) == ("fig.png", "fig.svg")
    with Image.open(png) as im:
        assert im.format == "PNG" and im.size == (640, 400) and im.mode == "RGB"
        pixels = np.asarray(im)
    assert (pixels != 255).any(axis=2).mean() > 0.02  # something was drawn
    texts = _svg_texts(svg)
    for label in (
        "number of frames N",
        "variance [mm²]",
        "Median of N samples, σ = 30 mm",
        "Cramér–Rao bound σ²/(2N)",
        "theory",
        "Monte-Carlo",
    ):
        assert label in texts, (label, texts)
    assert svg.read_text().startswith("<?xml") and "<svg" in svg.read_text()
    assert sorted(p.name for p in png.parent.iterdir()) == ["fig.png", "fig.svg"]
    assert plot.render("svg") == svg.read_bytes()  # reproducible (no date, fixed ids)


def test_log_axes_and_limits(tmp_path: Path) -> None:
    x = np.logspace(0, 3, 7)
    plot = line_plot(
        [Series(x, x**2, "y = x²")], log_x=True, log_y=True, xlim=(1, 1000), ylim=(1, 1e6)
    )
    fig = plot.figure()
    ax = fig.axes[0]
    assert ax.get_xscale() == "log" and ax.get_yscale() == "log"
    assert ax.get_xlim() == pytest.approx((1, 1000)) and ax.get_ylim() == pytest.approx((1, 1e6))
    png, _ = plot.save(tmp_path / "loglog")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(InputError, match="format"):
        plot.render("jpg")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="thickness"):
        line_plot([Series([1, 2], [1, 2], thickness=0)])
