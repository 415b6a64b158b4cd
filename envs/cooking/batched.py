"""B kitchens of one layout stepped at once, for training and evaluation (no PettingZoo overhead).

The rules are the pure functions of `envs.cooking.world`, the observations those of
`envs.cooking.observation`; this class keeps the state, the step counters, the sub-goal
bookkeeping and a seeded generator for random starts. Same interface as `BatchedParticleWorld`.

| array          | shape        | dtype   | meaning                                               |
|----------------|--------------|---------|-------------------------------------------------------|
| `recipes_BN`   | (B, N)       | int     | recipe index (into `RECIPE_NAMES`) of every agent     |
| `state`        | CookingState | int     | positions, holders, plates, states, deliveries        |
| `obs_BND`      | (B, N, D)    | float32 | every agent's observation, D = 12 N + 164             |
| `rewards_BN`   | (B, N)       | float64 | +20 dish, -0.01 per step while undelivered, sub-goals |
| `terminated_B` | (B,)         | bool    | every agent's dish delivered after this step          |
| `truncated_B`  | (B,)         | bool    | step counter reached `max_steps`, not terminated      |

Sub-goal rewards (off unless `sub_goal_reward > 0`): an agent whose dish is undelivered earns
`sub_goal_reward` for every step of its recipe graph (prepare an item, plate an item; see
`recipe_progress`) beyond the most it has had done since the episode started, so undoing and
redoing a step earns nothing. 1.0 (`SUB_GOAL_REWARD`) is the documented default when enabled.

`step` never resets: `next_obs_BND` is the true next observation, so the trainer can store the
transition before calling `reset_where(terminated_B | truncated_B)`. Everything is deterministic
given `seed` (which only matters with `random_starts=True`).
"""

from __future__ import annotations

import numpy as np

from envs.batched import BatchedWorlds, StepResult
from envs.cooking.layouts import Layout, get_layout
from envs.cooking.observation import observations
from envs.cooking.recipes import PLATE, RECIPE_NAMES, recipe_indices
from envs.cooking.world import (
    DISH_REWARD,
    N_ACTIONS,
    TIME_PENALTY,
    CookingState,
    carry_along,
    cell_kinds,
    recipe_progress,
    start_states,
    step_state,
)

SUB_GOAL_REWARD = 1.0


class BatchedCookingWorld(BatchedWorlds):
    """B independent kitchens of one layout with N agents each; see the module docstring."""

    def __init__(
        self,
        layout: str | Layout,
        recipes_BN: np.ndarray,
        *,
        max_steps: int = 400,
        seed: int | None = None,
        sub_goal_reward: float = 0.0,
        random_starts: bool = False,
    ) -> None:
        if max_steps < 1:
            raise ValueError(f"max_steps: expected >= 1, got {max_steps}")
        if not np.isfinite(sub_goal_reward) or sub_goal_reward < 0:
            raise ValueError(
                f"sub_goal_reward: expected a finite value >= 0, got {sub_goal_reward}"
            )
        self.layout = get_layout(layout)
        self._goals_BN = self._as_recipes(recipes_BN, None)
        self.max_steps = max_steps
        self.sub_goal_reward = float(sub_goal_reward)
        self.random_starts = random_starts
        self._rng = np.random.default_rng(seed)
        self._state = self._fresh(self.n_envs)
        self._steps_B = np.zeros(self.n_envs, dtype=np.int64)
        self._best_BN = recipe_progress(self.layout, self._state, self._goals_BN).count_BN
        self._last_obs_BND = self.observe()

    def reseed(self, seed: int | None) -> None:
        """Restart the generator of random starts (used by the PettingZoo env's reset(seed))."""
        self._rng = np.random.default_rng(seed)

    def _as_recipes(self, recipes_BN: np.ndarray, shape: tuple[int, ...] | None) -> np.ndarray:
        recipes_BN = recipe_indices(recipes_BN, "recipes_BN")
        n = self.layout.n_agents
        if recipes_BN.ndim != 2 or recipes_BN.shape[0] < 1 or recipes_BN.shape[1] != n:
            raise ValueError(
                f"recipes_BN: expected shape (B >= 1, {n}) for layout {self.layout.name!r} "
                f"with {n} agents, got {recipes_BN.shape}"
            )
        if shape is not None and recipes_BN.shape != shape:
            raise ValueError(f"recipes_BN: expected shape {shape}, got {recipes_BN.shape}")
        return recipes_BN

    def _fresh(self, n_envs: int) -> CookingState:
        return start_states(self.layout, n_envs, self._rng if self.random_starts else None)

    @property
    def recipes(self) -> np.ndarray:
        """Recipe indices, shape (B, N) (a copy)."""
        return self._goals_BN.copy()

    goals = recipes

    def recipe_names(self, b: int = 0) -> tuple[str, ...]:
        return tuple(RECIPE_NAMES[r] for r in self._goals_BN[b])

    @property
    def state(self) -> CookingState:
        """Current state (a copy)."""
        return self._state.copy()

    @property
    def steps(self) -> np.ndarray:
        """Steps taken since each kitchen's last reset, shape (B,) (a copy)."""
        return self._steps_B.copy()

    def set_goals(self, recipes_BN: np.ndarray) -> None:
        """Replace the recipes (same B and N); states, counters and deliveries are kept, the
        sub-goal baseline restarts from the current progress of the new recipes."""
        self._goals_BN = self._as_recipes(recipes_BN, self._goals_BN.shape)
        self._best_BN = recipe_progress(self.layout, self._state, self._goals_BN).count_BN

    set_recipes = set_goals

    def observe(self) -> np.ndarray:
        """Every agent's observation of the current state, shape (B, N, D), float32."""
        self._last_obs_BND = observations(self.layout, self._state)
        return self._last_obs_BND.copy()

    def reset(self, states: CookingState | None = None) -> np.ndarray:
        """Start every kitchen afresh: from `states` if given, else from the layout's start."""
        self._state = self._fresh(self.n_envs) if states is None else self._checked(states)
        self._steps_B[:] = 0
        self._best_BN = recipe_progress(self.layout, self._state, self._goals_BN).count_BN
        return self.observe()

    def _restart(self, mask_B: np.ndarray, n_reset: int) -> None:
        """The masked kitchens back at their start (`reset_where`)."""
        fresh = self._fresh(n_reset)
        for mine, new in zip(self._state, fresh, strict=True):
            mine[mask_B] = new
        self._steps_B[mask_B] = 0
        progress = recipe_progress(self.layout, self._state, self._goals_BN).count_BN
        self._best_BN[mask_B] = progress[mask_B]

    def step(self, actions_BN: np.ndarray) -> StepResult:
        """Advance every kitchen one step with the actions of every agent, shape (B, N)."""
        actions_BN = np.asarray(actions_BN)
        if actions_BN.shape != self._goals_BN.shape:
            raise ValueError(
                f"actions_BN: expected shape {self._goals_BN.shape}, got {actions_BN.shape}"
            )
        if actions_BN.dtype.kind not in "iu":
            raise ValueError(f"actions_BN: expected integers, got dtype {actions_BN.dtype}")
        if actions_BN.min() < 0 or actions_BN.max() >= N_ACTIONS:
            raise ValueError(f"actions_BN: expected values in 0..{N_ACTIONS - 1}")
        waiting_BN = ~self._state.delivered
        self._state, served_BN = step_state(
            self.layout, self._state, actions_BN.astype(np.int64), self._goals_BN
        )
        self._steps_B += 1
        rewards_BN = DISH_REWARD * served_BN - TIME_PENALTY * waiting_BN
        if self.sub_goal_reward > 0:
            count_BN = recipe_progress(self.layout, self._state, self._goals_BN).count_BN
            gain_BN = np.maximum(count_BN - self._best_BN, 0) * waiting_BN
            self._best_BN = np.maximum(self._best_BN, count_BN)
            rewards_BN = rewards_BN + self.sub_goal_reward * gain_BN
        terminated_B = np.all(self._state.delivered, axis=-1)
        truncated_B = (self._steps_B >= self.max_steps) & ~terminated_B
        return StepResult(self.observe(), rewards_BN, terminated_B, truncated_B)

    def _checked(self, states: CookingState) -> CookingState:
        """`states` as a copy after checking shapes and the invariants the rules rely on."""
        expected = start_states(self.layout, self.n_envs)
        if not isinstance(states, CookingState):
            raise ValueError(f"states: expected a CookingState, got {type(states).__name__}")
        for name, have, want in zip(CookingState._fields, states, expected, strict=True):
            if np.shape(have) != want.shape:
                raise ValueError(
                    f"states.{name}: expected shape {want.shape}, got {np.shape(have)}"
                )
        s = CookingState(
            *(np.asarray(a, dtype=w.dtype).copy() for a, w in zip(states, expected, strict=True))
        )
        floor_BN = cell_kinds(self.layout, s.agent_rc) == 0
        if not floor_BN.all():
            raise ValueError("states.agent_rc: every agent must stand on a floor cell")
        same = np.all(s.agent_rc[:, :, None] == s.agent_rc[:, None, :], -1)
        if np.any(same.sum(-1) > 1):
            raise ValueError("states.agent_rc: two agents on one cell")
        if s.obj_holder.min() < -1 or s.obj_holder.max() >= self.n_agents:
            raise ValueError(f"states.obj_holder: expected -1 or an agent 0..{self.n_agents - 1}")
        if np.any(np.sum(s.obj_holder[:, None, :] == np.arange(self.n_agents)[:, None], -1) > 1):
            raise ValueError("states.obj_holder: an agent holds more than one object")
        if s.obj_state.min() < 0 or s.obj_state.max() > 2:
            raise ValueError("states.obj_state: expected 0 (raw), 1 (chopped) or 2 (blended)")
        plates = np.flatnonzero(self.layout.object_kinds_O == PLATE)
        if not np.all(np.isin(s.obj_plate, [-1, *plates.tolist()])):
            raise ValueError("states.obj_plate: expected -1 or the object index of a plate")
        carry_along(s)  # held / plated objects sit where their holder / plate is
        return s
