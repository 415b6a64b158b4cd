"""Rendering: frame shape and dtype, frames that depend on the state, GIF output."""

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from envs.particle.render import render_frame, save_gif


def test_frame_shape_dtype_and_content() -> None:
    a = render_frame(np.array([[0.1, 0.5, 0, 0], [0.9, 0.9, 0, 0]]), ["a2", "b3"])
    b = render_frame(np.array([[0.5, 0.5, 0, 0], [0.9, 0.9, 0, 0]]), ["a2", "b3"])
    assert a.shape == (480, 480, 3) and a.dtype == np.uint8
    assert not np.array_equal(a, b)
    small = render_frame(np.array([[0.5, 0.5, 0, 0]]), ["c"], size=64)
    assert small.shape == (64, 64, 3)
    # the target of agent 0 (a2: left edge, middle row) is tinted, a far-away cell is white
    assert a[240, 20].tolist() != [255, 255, 255]
    assert a[460, 300].tolist() == [255, 255, 255]


def test_bad_render_input() -> None:
    with pytest.raises(ValueError, match="state_N4"):
        render_frame(np.zeros((2, 4)), ["a2"])


def test_gif_written(tmp_path: Path) -> None:
    frames = [render_frame(np.array([[x, 0.5, 0, 0]]), ["a2"], size=96) for x in (0.1, 0.5, 0.9)]
    path = save_gif(frames, tmp_path / "ep.gif", fps=10)
    with Image.open(path) as gif:
        assert gif.format == "GIF" and getattr(gif, "n_frames", 1) == 3 and gif.size == (96, 96)
