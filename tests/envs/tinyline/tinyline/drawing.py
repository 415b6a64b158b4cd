"""How the console draws the corridor. Coordinates come out as numpy scalars on purpose (a
drawing written with numpy arithmetic does that): the console's JSON must take them."""

from __future__ import annotations

from typing import Any

import numpy as np

from envs.scene import AgentMark, Scene, SceneFrame, rect
from tinyline.env import CELLS


class CorridorDrawing:
    def scene(self, env: Any) -> Scene:
        cells = tuple(
            rect(
                np.float32(k),
                np.float32(0),
                np.float32(1),
                np.float32(1),
                stroke="#888888",
                label=f"c{k}",
            )
            for k in range(CELLS)
        )
        return Scene(
            np.float64(CELLS),
            np.float32(1.0),
            True,
            np.float32(0.3),
            ("#1f77b4", "#ff7f0e", "#2ca02c"),
            cells,
        )

    def scene_frame(self, env: Any) -> SceneFrame:
        marks = tuple(
            AgentMark(
                np.int64(i),
                np.float32(cell) + np.float32(0.5),
                np.float32(0.5),
                f"agent {i} on c{cell}",
            )
            for i, cell in enumerate(env.cells)
        )
        return SceneFrame(marks)
