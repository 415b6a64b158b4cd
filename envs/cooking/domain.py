"""The cooking world as an `envs.base.Domain`: recipe catalogue, observation layout and views.

Task and impact networks see *pair views*: the observation of a two-agent kitchen, 188 features
(two agent blocks, then every object and station slot; `envs.cooking.observation`). From an
N-agent observation (12 N + 164 features):

| view          | built from the ego's observation                               | shape        |
|---------------|----------------------------------------------------------------|--------------|
| task views    | [ego, other_j] + shared blocks, j = 1..N-1                     | (B, N-1, 188)|
| impact view   | [ego, other_k] + shared blocks                                 | (B, 188)     |
| partner view  | [other_k, ego] + shared blocks, every rel_x/rel_y recomputed   | (B, 188)     |
|               | relative to other_k (exact: see `observation.perspective`)     |              |

With two agents the impact view *is* the observation and the partner view is exactly the
partner's own observation. The other agents' blocks are dropped from a pair view, but the objects
they hold stay in the object slots (flagged `held`, at their holder's cell).

With N = 1 the task network still takes a pair: the missing partner is an *absent* block (all
zeros, `present` = 0), which a trained network sees nowhere else. It is a placeholder, not a
promise: train with two agents. Goals are recipe names; the reward of a goal is the own-recipe
reward of `envs.cooking.world` (+20 dish, -0.01 per step while undelivered).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from envs.base import BlendNormalisation, DomainCounts
from envs.cooking.env import CookingEnv
from envs.cooking.layouts import MAX_AGENTS
from envs.cooking.observation import AGENT_DIM, SERVED, feature_names, obs_dim, select_agents
from envs.cooking.recipes import RECIPE_NAMES
from envs.cooking.scene import cooking_frame, cooking_scene
from envs.cooking.world import ACTION_MEANINGS
from envs.scene import Scene, SceneFrame


class CookingDomain(DomainCounts):
    """Domain description of the cooking world (implements `envs.base.Domain`)."""

    name = "cooking"
    goals: tuple[str, ...] = RECIPE_NAMES
    action_meanings: tuple[str, ...] = ACTION_MEANINGS
    max_agents = MAX_AGENTS
    pair_obs_dim = obs_dim(2)
    # eq. 8 on the raw Q-vectors: task and impact Q are returns of the same dish rewards, and
    # standardising a nearly flat impact Q let it outvote the task (reports/cooking/README.md)
    blend_normalisation: BlendNormalisation = "none"
    goal_is_final: bool = True  # a served dish stays served; no time penalty after it

    def obs_dim(self, n_agents: int) -> int:
        self._check_n(n_agents)
        return obs_dim(n_agents)

    def observation_layout(self, n_agents: int) -> list[str]:
        self._check_n(n_agents)
        return feature_names(n_agents)

    def _checked(self, obs_BD: np.ndarray, n_agents: int) -> np.ndarray:
        dim = self.obs_dim(n_agents)
        obs_BD = np.asarray(obs_BD, dtype=np.float32)
        if obs_BD.ndim != 2 or obs_BD.shape[1] != dim:
            raise ValueError(
                f"obs_BD: expected shape (B, {dim}) for {n_agents} agents, got {obs_BD.shape}"
            )
        return obs_BD

    def _check_partner(self, n_agents: int, partner: int) -> None:
        if not 1 <= partner <= n_agents - 1:
            raise ValueError(
                f"partner: expected an other agent's block 1..{n_agents - 1}, got {partner}"
            )

    def task_views(self, obs_BD: np.ndarray, n_agents: int) -> np.ndarray:
        obs_BD = self._checked(obs_BD, n_agents)
        if n_agents == 1:
            absent = np.zeros((obs_BD.shape[0], AGENT_DIM), dtype=np.float32)
            view = np.concatenate([obs_BD[:, :AGENT_DIM], absent, obs_BD[:, AGENT_DIM:]], axis=1)
            return view[:, None, :]
        views = [select_agents(obs_BD, n_agents, [0, j]) for j in range(1, n_agents)]
        return np.stack(views, axis=1)

    def impact_view(self, obs_BD: np.ndarray, n_agents: int, partner: int) -> np.ndarray:
        obs_BD = self._checked(obs_BD, n_agents)
        self._check_partner(n_agents, partner)
        return select_agents(obs_BD, n_agents, [0, partner])

    def partner_view(self, obs_BD: np.ndarray, n_agents: int, partner: int) -> np.ndarray:
        obs_BD = self._checked(obs_BD, n_agents)
        self._check_partner(n_agents, partner)
        return select_agents(obs_BD, n_agents, [partner, 0])

    def goal_reached(self, obs_BD: np.ndarray, n_agents: int, goal: str) -> np.ndarray:
        """Whether the ego's dish has been served (its `served` feature), (B,) bool. Final: no
        later action changes the cook's own return (`goal_is_final`)."""
        return self._checked(obs_BD, n_agents)[:, SERVED] > 0.5

    def goal_kept(self, obs_BD: np.ndarray, n_agents: int, goal: str) -> None:
        """None: a served dish stays served whatever the cook does (`goal_is_final`)."""
        return None

    def scene(self, env: Any) -> Scene:
        """The kitchen's cells and stations (`envs.cooking.scene`)."""
        kitchen = _cooking_env(env)
        return cooking_scene(kitchen.layout, kitchen.recipes)

    def scene_frame(self, env: Any) -> SceneFrame:
        kitchen = _cooking_env(env)
        return cooking_frame(kitchen.layout, kitchen.world.state, kitchen.recipes)


def _cooking_env(env: Any) -> CookingEnv:
    if not isinstance(env, CookingEnv):
        raise TypeError(f"env: expected a kitchen env, got {type(env).__name__}")
    return env


COOKING = CookingDomain()
