"""render_anatomy_layout: the picture of the muscles over the skin has the asked size, colours and background."""

from __future__ import annotations

from pathlib import Path

import pytest
from matplotlib import image as mpimg

from facecap.anatomy import render_anatomy_layout
from facecap.errors import InputError


def test_layout_picture(anatomy, tmp_path: Path) -> None:
    path = tmp_path / "layout.png"
    render_anatomy_layout(anatomy, path, size_px=(900, 500))
    img = mpimg.imread(path)
    assert img.shape[:2] == (500, 900)
    rgb = img[..., :3]
    # the muscles are coloured (saturated pixels), the skin grey, the background white
    saturation = rgb.max(axis=2) - rgb.min(axis=2)
    assert (saturation > 0.25).mean() > 0.02
    assert (rgb.min(axis=2) > 0.98).mean() > 0.2
    with pytest.raises(InputError, match="size_px"):
        render_anatomy_layout(anatomy, path, size_px=(10, 10))
