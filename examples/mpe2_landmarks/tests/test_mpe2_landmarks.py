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


def test_goal_kept_predicts_the_world() -> None:
    """`goal_kept` says, for every action, whether MPE2's own step and the rests after it keep
    the agent within `REACHED` of its landmark: checked against the world on random states."""
    from mpe2_landmarks.env import LANDMARKS, LANDMARKS_DOMAIN, REACHED

    rng = np.random.default_rng(0)
    lost = kept_count = 0
    for trial in range(150):
        position = LANDMARKS[0] + rng.uniform(-0.1, 0.1, 2)
        velocity = rng.uniform(-0.5, 0.5, 2)
        obs = np.concatenate([position, velocity])[None].astype(np.float32)
        kept = LANDMARKS_DOMAIN.goal_kept(obs, 1, "l0")[0]
        for action in range(5):
            env = make_env("mpe2_landmarks", ("l0",), max_steps=1000)
            env.reset(seed=trial)
            agent = env.world.agents[0]
            agent.state.p_pos = obs[0, :2].astype(np.float64)
            agent.state.p_vel = obs[0, 2:].astype(np.float64)
            inside = True
            for t in range(60):
                env.agents = list(env.possible_agents)  # keep stepping after an arrival
                env.step({"agent_0": action if t == 0 else 0})
                inside &= bool(np.linalg.norm(agent.state.p_pos - LANDMARKS[0]) < REACHED)
            assert inside == bool(kept[action]), (trial, action)
            kept_count += inside
            lost += not inside
    assert kept_count > 50 and lost > 50  # both outcomes were exercised
