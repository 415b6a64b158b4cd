"""The cooking coexistence world (paper §4.3) as a PettingZoo `ParallelEnv`.

An Overcooked-style kitchen in which every agent cooks its *own* recipe: prepare the ingredients
with the right tool (cutting board, blender), put them together on a plate, walk the plate onto a
delivery square. Kitchens are text layouts (`envs.cooking.layouts`); the rules are in
`envs.cooking.world`, the observation in `envs.cooking.observation`.

| property           | value                                                                   |
|--------------------|-------------------------------------------------------------------------|
| import             | `from envs.cooking.env import CookingEnv`                               |
| agents             | `agent_0` .. `agent_{N-1}`: the digits of the layout, N in 1..4         |
| goals              | one recipe per agent (`RECIPE_NAMES`): ChoppedTomato,                   |
|                    | TomatoLettuceSalad, CarrotBanana, OnionSoup, BananaSmoothie             |
| actions            | Discrete(5): 0 stay, 1 up (row - 1), 2 down, 3 left (column - 1), 4     |
|                    | right; walking into a counter or station interacts with it              |
| observation        | Box(11 N + 164) float32, the same length for every layout: agent blocks |
|                    | (self first), ingredient, plate and station slots; table in observation |
| reward of agent i  | +20 when its dish is delivered, -0.01 per step while it is undelivered, |
|                    | + sub-goal rewards if enabled (1.0 per recipe step, or the given value) |
| termination        | every agent's dish delivered (all agents end together)                  |
| truncation         | `max_steps` steps (400 in the paper)                                    |
| start state        | the layout's; `random_starts=True` puts every agent on a random cell of |
|                    | its start area; or `reset(options={"state": CookingState with B = 1})`  |
| infos              | `{"recipe": name, "delivered": bool}` per agent                         |
| render modes       | `"rgb_array"` (48 px per cell)                                          |

The env steps a `BatchedCookingWorld` holding one kitchen, so it and the batched trainer
simulator share one implementation of the rules.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium
import numpy as np

from envs.cooking.batched import SUB_GOAL_REWARD, BatchedCookingWorld
from envs.cooking.layouts import BLENDER, BOARD, DELIVERY, Layout, get_layout
from envs.cooking.observation import observation_bounds
from envs.cooking.recipes import BLENDED, CHOPPED, INGREDIENTS, PLATE, RECIPES, recipe_indices
from envs.cooking.render import render_frame
from envs.cooking.world import N_ACTIONS, CookingState
from envs.parallel import OneWorldEnv


def sub_goal_value(sub_goal_rewards: bool | float) -> float:
    """The per-step sub-goal reward: False -> 0, True -> `SUB_GOAL_REWARD`, a number -> itself."""
    if isinstance(sub_goal_rewards, bool):
        return SUB_GOAL_REWARD if sub_goal_rewards else 0.0
    return float(sub_goal_rewards)


def check_recipes_fit(layout: Layout, recipes: Sequence[str]) -> None:
    """ValueError if a recipe needs an ingredient kind, a plate or a station the layout lacks
    (whether the agent can *reach* them is the layout's business: see `coexistence`)."""
    kinds = set(layout.object_kinds_O.tolist())
    has = {
        "plate": PLATE in kinds,
        "delivery square": len(layout.stations[DELIVERY]) > 0,
        "cutting board": len(layout.stations[BOARD]) > 0,
        "blender": len(layout.stations[BLENDER]) > 0,
    }
    tool_of_state = {CHOPPED: "cutting board", BLENDED: "blender"}
    for name in recipes:
        recipe = RECIPES[int(recipe_indices([name])[0])]
        missing = [INGREDIENTS[k] for k, _ in recipe.items if k not in kinds]
        needs = ["plate", "delivery square"] + [
            tool_of_state[s] for _, s in recipe.items if s in tool_of_state
        ]
        missing += [n for n in dict.fromkeys(needs) if not has[n]]
        if missing:
            raise ValueError(
                f"recipes: {name} needs {', '.join(missing)}, which layout "
                f"{layout.name!r} does not have"
            )


class CookingEnv(OneWorldEnv):
    """N cooks with their own recipes in one kitchen; see the module docstring."""

    metadata: dict[str, Any] = {  # noqa: RUF012 (PettingZoo's class attribute)
        "name": "cooking_coexistence_v0",
        "render_modes": ["rgb_array"],
        "render_fps": 8,
        "is_parallelizable": True,
    }

    def __init__(
        self,
        layout: str | Layout = "coexistence",
        recipes: Sequence[str] = ("TomatoLettuceSalad", "CarrotBanana"),
        max_steps: int = 400,
        sub_goal_rewards: bool | float = False,
        render_mode: str | None = None,
        random_starts: bool = False,
    ) -> None:
        self.layout = get_layout(layout)
        if isinstance(recipes, str) or len(recipes) != self.layout.n_agents:
            raise ValueError(
                f"recipes: expected one recipe per agent of layout {self.layout.name!r} "
                f"({self.layout.n_agents}), got {recipes!r}"
            )
        self.recipes: tuple[str, ...] = tuple(recipes)
        check_recipes_fit(self.layout, self.recipes)
        self.max_steps = max_steps
        self.world: BatchedCookingWorld = BatchedCookingWorld(
            self.layout,
            recipe_indices(self.recipes)[None],
            max_steps=max_steps,
            seed=None,
            sub_goal_reward=sub_goal_value(sub_goal_rewards),
            random_starts=random_starts,
        )
        low, high = observation_bounds(self.layout.n_agents)
        self._setup_agents(self.layout.n_agents, low, high, N_ACTIONS, render_mode)

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, dict[str, Any]]]:
        if seed is not None:
            self.world.reseed(seed)
        start = None if options is None else options.get("state")
        if start is not None and not isinstance(start, CookingState):
            raise ValueError(
                f'options["state"]: expected a CookingState, got {type(start).__name__}'
            )
        return self._started(self.world.reset(start))

    def _infos(self) -> dict[str, dict[str, Any]]:
        delivered_N = self.world.state.delivered[0]
        return {
            a: {"recipe": self.recipes[i], "delivered": bool(delivered_N[i])}
            for i, a in enumerate(self.possible_agents)
        }

    def state(self) -> np.ndarray:
        """agent_0's observation: it holds every agent's and object's absolute position."""
        return self.world.observe()[0, 0]

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            gymnasium.logger.warn("render() needs render_mode='rgb_array' at construction")
            return None
        return render_frame(self.layout, self.world.state, self.recipes)


def parallel_env(**kwargs: Any) -> CookingEnv:
    """Factory in PettingZoo's style: `parallel_env(layout="open", recipes=(...))`."""
    return CookingEnv(**kwargs)


def make_cooking_env(goals: Sequence[str], **kwargs: Any) -> CookingEnv:
    """The registry's factory: the goals are the agents' recipes."""
    return CookingEnv(recipes=goals, **kwargs)
