"""The plugin's own tests, with it installed: coexist's conformance check, and the physics that
makes it a coexistence problem (an agent in the way is pushed, and slows its partner)."""

from __future__ import annotations

import numpy as np

from envs.check import assert_env_conforms
from envs.registry import make_env


def test_it_conforms() -> None:
    assert_env_conforms("mpe2_landmarks")


def test_an_agent_in_the_way_slows_its_partner() -> None:
    def steps_to_arrive(blocker_at: tuple[float, float]) -> int:
        env = make_env("mpe2_landmarks", ("l1", "l0"), max_steps=200)
        env.reset(seed=0)
        ego, other = env.world.agents
        ego.state.p_pos, other.state.p_pos = np.array([-0.6, -0.6]), np.array(blocker_at)
        for t in range(1, 200):
            env.step({"agent_0": 2, "agent_1": 0})  # the ego pushes right, the other rests
            if np.linalg.norm(ego.state.p_pos - np.array([0.6, -0.6])) < 0.1:
                return t
        return 200

    assert steps_to_arrive((0.0, -0.6)) > steps_to_arrive((0.0, 0.6))
