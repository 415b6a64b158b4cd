"""Drawing the particle world to RGB arrays (Pillow, no matplotlib) and writing GIFs.

| element        | drawn as                                                        |
|----------------|-----------------------------------------------------------------|
| grid           | faint 5×5 grid lines                                            |
| target area    | filled rectangle in the agent's colour, translucent (alpha 70)  |
| influence area | hollow rectangle outline in the agent's colour                  |
| agent          | disc in the agent's colour with a dark rim                      |

The world's y axis points up, so image row = (1 - y) * size.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from envs.particle.goals import GRID_SIZE, INFLUENCE_BOXES_G4, TARGET_BOXES_G4, goal_index

AGENT_COLOURS: tuple[tuple[int, int, int], ...] = (
    (31, 119, 180),  # blue
    (214, 39, 40),  # red
    (44, 160, 44),  # green
    (255, 127, 14),  # orange
    (148, 103, 189),  # purple
)
TARGET_ALPHA = 70
BACKGROUND = (255, 255, 255, 255)
GRID_COLOUR = (225, 225, 225, 255)


def _box_pixels(box: np.ndarray, size: int) -> tuple[float, float, float, float]:
    """(left, top, right, bottom) pixel rectangle of an (x_min, x_max, y_min, y_max) box."""
    x_lo, x_hi, y_lo, y_hi = (float(v) for v in box)
    last = size - 1
    return x_lo * last, (1.0 - y_hi) * last, x_hi * last, (1.0 - y_lo) * last


def render_frame(state_N4: np.ndarray, goals: Sequence[str], size: int = 480) -> np.ndarray:
    """One frame of the world, shape (size, size, 3), dtype uint8."""
    state_N4 = np.asarray(state_N4, dtype=np.float64)
    if state_N4.ndim != 2 or state_N4.shape[1] != 4 or state_N4.shape[0] != len(goals):
        raise ValueError(f"state_N4: expected shape ({len(goals)}, 4), got {state_N4.shape}")
    if not 1 <= len(goals) <= len(AGENT_COLOURS):
        raise ValueError(f"goals: expected 1..{len(AGENT_COLOURS)} goals, got {len(goals)}")
    if size < 16:
        raise ValueError(f"size: expected >= 16 pixels, got {size}")
    goal_idx = [goal_index(g) for g in goals]

    image = Image.new("RGBA", (size, size), BACKGROUND)
    grid = ImageDraw.Draw(image)
    for k in range(GRID_SIZE + 1):
        p = round(k * (size - 1) / GRID_SIZE)
        grid.line([(p, 0), (p, size - 1)], fill=GRID_COLOUR)
        grid.line([(0, p), (size - 1, p)], fill=GRID_COLOUR)

    # Translucent fills need their own layer: ImageDraw replaces pixels instead of blending.
    areas = Image.new("RGBA", (size, size), (0, 0, 0, 0))
    draw_areas = ImageDraw.Draw(areas)
    outline = max(2, size // 160)
    for colour, g in zip(AGENT_COLOURS, goal_idx, strict=False):
        draw_areas.rectangle(_box_pixels(TARGET_BOXES_G4[g], size), fill=(*colour, TARGET_ALPHA))
    image = Image.alpha_composite(image, areas)

    draw = ImageDraw.Draw(image)
    for colour, g in zip(AGENT_COLOURS, goal_idx, strict=False):
        draw.rectangle(
            _box_pixels(INFLUENCE_BOXES_G4[g], size), outline=(*colour, 255), width=outline
        )
    radius = max(3.0, size / 40)
    for colour, (x, y) in zip(AGENT_COLOURS, state_N4[:, :2], strict=False):
        cx, cy = x * (size - 1), (1.0 - y) * (size - 1)
        draw.ellipse(
            (cx - radius, cy - radius, cx + radius, cy + radius),
            fill=(*colour, 255),
            outline=(40, 40, 40, 255),
            width=max(1, outline // 2),
        )
    return np.asarray(image.convert("RGB"), dtype=np.uint8)


def save_gif(frames: Sequence[np.ndarray], path: str | Path, fps: int = 20) -> Path:
    """Write RGB frames (H, W, 3) uint8 as a looping GIF; returns the path."""
    if len(frames) == 0:
        raise ValueError("frames: expected at least one frame")
    if fps < 1:
        raise ValueError(f"fps: expected >= 1, got {fps}")
    path = Path(path)
    images = [Image.fromarray(np.asarray(f, dtype=np.uint8)) for f in frames]
    images[0].save(
        path,
        save_all=True,
        append_images=images[1:],
        duration=max(1, round(1000 / fps)),
        loop=0,
    )
    return path
