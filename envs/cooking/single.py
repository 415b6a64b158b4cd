"""A gymnasium single-agent view of the cooking world: one cook controlled, the others scripted.

| property     | value                                                                       |
|--------------|-----------------------------------------------------------------------------|
| agent        | `agent` (an index of the layout's cooks) is controlled by `step(action)`    |
| partners     | `{index: policy}`; a policy is `policy(env, index) -> action` with `env` the |
|              | underlying `CookingEnv` (e.g. a `ScriptedCook`); unlisted cooks stand still  |
| observation  | the controlled cook's observation, Box(11 N + 164) float32                  |
| reward       | the controlled cook's reward (+20 dish, -0.01 per step while undelivered)   |
| terminated   | the controlled cook's dish is delivered, or every cook's is                 |
| truncated    | `max_steps` steps                                                           |
| infos        | the controlled cook's `{"recipe", "delivered"}`                             |
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import gymnasium
import numpy as np
from gymnasium.spaces import Box, Discrete

from envs.cooking.env import CookingEnv
from envs.cooking.layouts import Layout
from envs.cooking.world import N_ACTIONS

PartnerPolicy = Callable[[CookingEnv, int], int]


class CookingSingleAgentEnv(gymnasium.Env[np.ndarray, np.int64]):
    """One controlled cook in a `CookingEnv`; see the module docstring."""

    metadata: dict[str, Any] = {"render_modes": ["rgb_array"], "render_fps": 8}  # noqa: RUF012

    def __init__(
        self,
        layout: str | Layout = "coexistence",
        recipes: Sequence[str] = ("TomatoLettuceSalad", "CarrotBanana"),
        agent: int = 0,
        partners: Mapping[int, PartnerPolicy] | None = None,
        max_steps: int = 400,
        sub_goal_rewards: bool | float = False,
        render_mode: str | None = None,
        random_starts: bool = False,
    ) -> None:
        self.env = CookingEnv(
            layout=layout,
            recipes=recipes,
            max_steps=max_steps,
            sub_goal_rewards=sub_goal_rewards,
            render_mode=render_mode,
            random_starts=random_starts,
        )
        n_agents = self.env.layout.n_agents
        if not 0 <= agent < n_agents:
            raise ValueError(f"agent: expected a cook index 0..{n_agents - 1}, got {agent}")
        self.partners = dict(partners or {})
        for index in self.partners:
            if index == agent or not 0 <= index < n_agents:
                raise ValueError(
                    f"partners: {index} is not another cook's index (0..{n_agents - 1})"
                )
        self.agent = agent
        self._name = self.env.possible_agents[agent]
        self.render_mode = render_mode
        self.observation_space: Box = self.env.observation_space(self._name)
        self.action_space: Discrete = Discrete(N_ACTIONS)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        obs, infos = self.env.reset(seed=seed, options=options)
        return obs[self._name], infos[self._name]

    def step(
        self, action: int | np.integer
    ) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        if not self.action_space.contains(action):
            raise ValueError(f"action: expected an integer in 0..{N_ACTIONS - 1}, got {action!r}")
        actions = {}
        for i, name in enumerate(self.env.possible_agents):
            policy = self.partners.get(i)
            actions[name] = int(policy(self.env, i)) if policy is not None else 0
        actions[self._name] = int(action)
        obs, rewards, terminated, truncated, infos = self.env.step(actions)
        done = terminated[self._name] or infos[self._name]["delivered"]
        if done:
            self.env.agents = []  # this view's episode is over even if the others still cook
        return (
            obs[self._name],
            rewards[self._name],
            bool(done),
            bool(truncated[self._name] and not done),
            infos[self._name],
        )

    def render(self) -> np.ndarray | None:
        return self.env.render()

    def close(self) -> None:
        self.env.close()
