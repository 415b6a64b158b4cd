"""The session benchmarks' scene: a store of every particle network (random weights at the
trainer's size), a seeded episode, and the JSON bodies of its steps and plain acts. Shared by
`benchmarks/session_bench.py` (over HTTP) and `benchmarks/session_breakdown.py` (in-process).
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np

from envs.particle.goals import GOAL_IDS

EGO_GOAL, PARTNER_GOALS = "a2", ("b3", "c1", "d4", "e0")


def build_store(url: str) -> str:
    """Every particle task and impact network (random weights) at `url`; returns the size."""
    from model_store import Lineage, impact_model_name, open_store, task_model_name
    from model_store.testing import qnet_spec, qnet_weights
    from trainer.config import TaskConfig

    hidden = TaskConfig().hidden
    spec = qnet_spec(obs_dim=8, n_actions=5, hidden=hidden)
    with open_store(url, create=True) as store:
        for g, goal in enumerate(GOAL_IDS):
            for k, (kind, name) in enumerate(
                (
                    ("task", task_model_name("particle", goal)),
                    ("impact", impact_model_name("particle", goal)),
                )
            ):
                store.create_model(
                    name,
                    env="particle",
                    kind=kind,
                    goals=[goal],
                    obs_dim=8,
                    n_actions=5,
                    exist_ok=True,
                )
                store.register_version(
                    name,
                    spec=spec,
                    weights=qnet_weights(spec, seed=2 * g + k),
                    lineage=Lineage(config={"alpha": 0.02}, seed=2 * g + k),
                    aliases=("production",),
                )
    return "-".join(map(str, (8, *hidden, 5)))


def episode(n_agents: int, steps: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The ego's observations (T, 4N) and the partners' actions (T, N-1) of a seeded episode
    with random actions (the world restarts when a state leaves the usual range)."""
    from envs.particle.scenarios import start_states
    from envs.particle.world import observations, step_state

    rng = np.random.default_rng(seed)
    state = start_states(seed, 1, n_agents)
    obs, actions = [], []
    for _ in range(steps):
        obs.append(observations(state)[0, 0])
        act_1N = rng.integers(0, 5, (1, n_agents))
        actions.append(act_1N[0, 1:])
        state = step_state(state, act_1N)
        if np.abs(state[..., :2]).max() > 1.5:
            state = start_states(int(rng.integers(1 << 30)), 1, n_agents)
    return np.asarray(obs, dtype=np.float64), np.asarray(actions, dtype=np.int64)


def act_bodies(obs_TD: np.ndarray, goals: tuple[str, ...]) -> list[bytes]:
    partners = [{"index": j + 1, "goal": g} for j, g in enumerate(goals)]
    return [
        json.dumps(
            {
                "env": "particle",
                "ego_goal": EGO_GOAL,
                "partners": partners,
                "method": "aail",
                "observation": o.round(6).tolist(),
            }
        ).encode()
        for o in obs_TD
    ]


def step_bodies(obs_TD: np.ndarray, actions_TP: np.ndarray, observed: bool) -> list[bytes]:
    """Step t sends o_t and the partners' a_{t-1} (the first body of a cycle repeats the last
    actions: every timed step carries evidence)."""
    bodies = []
    for t, o in enumerate(obs_TD):
        body: dict[str, Any] = {"observation": o.round(6).tolist()}
        if observed:
            prev = actions_TP[t - 1]  # t = 0: the last step's actions (the cycle wraps)
            body["observed"] = [{"index": j + 1, "action": int(a)} for j, a in enumerate(prev)]
        bodies.append(json.dumps(body).encode())
    return bodies
