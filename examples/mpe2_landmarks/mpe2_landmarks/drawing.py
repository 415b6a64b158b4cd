"""How the console draws the world: the landmarks once, the agents per step (world units shifted
from [-1, 1] to [0, 2], y up)."""

from __future__ import annotations

from typing import Any

from envs.scene import AgentMark, Scene, SceneFrame, circle
from mpe2_landmarks.env import AGENT_SIZE, GOALS, LANDMARKS, REACHED

COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c")


class LandmarksDrawing:
    def scene(self, env: Any) -> Scene:
        marks = tuple(
            circle(x + 1, y + 1, REACHED, fill="#dddddd", stroke="#888888", label=f"landmark {g}")
            for g, (x, y) in zip(GOALS, LANDMARKS, strict=True)
        )
        return Scene(2.0, 2.0, True, AGENT_SIZE, COLOURS, marks)

    def scene_frame(self, env: Any) -> SceneFrame:
        agents = tuple(
            AgentMark(i, a.state.p_pos[0] + 1, a.state.p_pos[1] + 1, f"agent {i} ({env.goals[i]})")
            for i, a in enumerate(env.world.agents)
        )
        return SceneFrame(agents)
