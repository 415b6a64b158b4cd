"""The particle world as a scene: the areas of each agent's goal, agents where the state puts
them, one colour per agent shared with the GIFs, and JSON the console can paint."""

import json

import numpy as np
import pytest

from envs.particle.domain import PARTICLE
from envs.particle.env import ParticleCoexistenceEnv
from envs.particle.goals import INFLUENCE_BOXES_G4, TARGET_BOXES_G4, goal_index
from envs.particle.render import AGENT_COLOURS
from envs.particle.scene import particle_frame, particle_scene
from envs.registry import make_env
from envs.scene import hex_colour


def _box(shape) -> list[float]:
    return [shape.x, shape.x + shape.w, shape.y, shape.y + shape.h]


def test_each_agent_has_its_target_and_influence_area_in_its_colour() -> None:
    scene = particle_scene(["a2", "b3"])
    assert (scene.width, scene.height, scene.y_up) == (1.0, 1.0, True)
    assert scene.agent_colours == tuple(hex_colour(c) for c in AGENT_COLOURS[:2])
    assert sum(s.kind == "line" for s in scene.shapes) == 12  # the 5×5 grid
    rects = [s for s in scene.shapes if s.kind == "rect"]
    targets = [s for s in rects if not s.dash]
    influences = [s for s in rects if s.dash]
    for i, goal in enumerate(["a2", "b3"]):
        g = goal_index(goal)
        np.testing.assert_allclose(_box(targets[i]), TARGET_BOXES_G4[g], atol=1e-12)
        np.testing.assert_allclose(_box(influences[i]), INFLUENCE_BOXES_G4[g], atol=1e-12)
        assert targets[i].fill == influences[i].stroke == scene.agent_colours[i]
        assert f"agent {i}" in targets[i].label and goal in influences[i].label


def test_agents_stand_where_the_env_state_puts_them() -> None:
    env = ParticleCoexistenceEnv(goals=("a2", "b3"))
    start = np.array([[0.1, 0.5, 0.0, 0.0], [0.7, 0.2, 0.0, 0.0]])
    env.reset(options={"state": start})
    frame = PARTICLE.scene_frame(env)
    assert [(a.index, a.x, a.y) for a in frame.agents] == [
        (0, pytest.approx(0.1), pytest.approx(0.5)),
        (1, pytest.approx(0.7), pytest.approx(0.2)),
    ]
    # agent 0 starts inside a2's target area (column a, row 2), agent 1 outside b3's
    assert frame.agents[0].status == "in target" and frame.agents[1].status == ""
    env.step({"agent_0": 4, "agent_1": 1})  # right, up
    moved = PARTICLE.scene_frame(env)
    assert moved.agents[0].x > 0.1 and moved.agents[1].y > 0.2
    assert PARTICLE.scene(env) == particle_scene(("a2", "b3"))


def test_json_is_rounded_and_names_its_fields() -> None:
    scene = particle_scene(["c"]).to_json()
    json.dumps(scene)  # JSON as it is
    rect = next(s for s in scene["shapes"] if s["kind"] == "rect")
    assert set(rect) >= {"x", "y", "w", "h", "fill", "opacity", "label"}
    frame = particle_frame(["c"], np.array([[1 / 3, 2 / 3, 0.0, 0.0]])).to_json()
    assert frame["agents"][0]["x"] == 0.3333 and frame["agents"][0]["y"] == 0.6667


def test_bad_input_is_refused() -> None:
    with pytest.raises(ValueError, match="state_N4"):
        particle_frame(["a2", "b3"], np.zeros((1, 4)))
    with pytest.raises(ValueError, match="goals"):
        particle_scene([])
    with pytest.raises(TypeError, match="particle"):
        PARTICLE.scene(make_env("cooking", ("TomatoLettuceSalad", "CarrotBanana")))
