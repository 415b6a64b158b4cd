"""The cooking coexistence world of the paper (§4.3-4.4): an Overcooked-style kitchen in which
every agent cooks its own recipe, with the Fig. 8 situation where one cook needs the other's carrot.

| module        | what |
|---------------|------|
| `layouts`     | the grid language, its parser (`LayoutError` with line/column), built-in kitchens |
| `recipes`     | ingredients, processing states, the recipe catalogue (the goals) |
| `world`       | the rules as pure numpy functions over B kitchens, recipe progress |
| `observation` | the fixed-length observation, its feature table, the perspective transform |
| `batched`     | `BatchedCookingWorld`: B kitchens stepped at once (trainer, evaluation) |
| `env`         | `CookingEnv`: the PettingZoo `ParallelEnv` (documentation table) |
| `single`      | `CookingSingleAgentEnv`: gymnasium env, one cook controlled, the others scripted |
| `domain`      | `COOKING`: the `envs.base.Domain` (recipe catalogue, pair views) |
| `navigation`  | shortest paths on the floor, walking to and into cells |
| `scripted`    | scripted cooks (one per recipe) and the carrot hand-over helper |
| `render`      | RGB frames and GIFs |
"""

from envs.cooking.batched import SUB_GOAL_REWARD, BatchedCookingWorld, StepResult
from envs.cooking.domain import COOKING, CookingDomain
from envs.cooking.env import CookingEnv, make_cooking_env, parallel_env
from envs.cooking.layouts import (
    BUILTIN_LAYOUTS,
    Layout,
    LayoutError,
    get_layout,
    load_layout,
    parse_layout,
)
from envs.cooking.observation import from_perspective, perspective
from envs.cooking.recipes import RECIPE_NAMES, RECIPES, Recipe
from envs.cooking.render import render_frame, save_gif
from envs.cooking.scripted import ScriptedCook, scripted_actions
from envs.cooking.single import CookingSingleAgentEnv
from envs.cooking.world import (
    ACTION_MEANINGS,
    DISH_REWARD,
    TIME_PENALTY,
    CookingState,
    RecipeProgress,
    recipe_progress,
)

__all__ = [
    "ACTION_MEANINGS",
    "BUILTIN_LAYOUTS",
    "COOKING",
    "DISH_REWARD",
    "RECIPES",
    "RECIPE_NAMES",
    "SUB_GOAL_REWARD",
    "TIME_PENALTY",
    "BatchedCookingWorld",
    "CookingDomain",
    "CookingEnv",
    "CookingSingleAgentEnv",
    "CookingState",
    "Layout",
    "LayoutError",
    "Recipe",
    "RecipeProgress",
    "ScriptedCook",
    "StepResult",
    "from_perspective",
    "get_layout",
    "load_layout",
    "make_cooking_env",
    "parallel_env",
    "parse_layout",
    "perspective",
    "recipe_progress",
    "render_frame",
    "save_gif",
    "scripted_actions",
]
