"""Ingredients, their processing states and the recipes (the goals of the cooking world).

Objects are ingredients (kinds 0..4) or plates (kind 5). An ingredient is raw, chopped (on a
cutting board) or blended (in a blender); a processed ingredient stays processed.

A recipe is a set of distinct (ingredient, state) *items* that must lie together on one plate,
with nothing else on it, when the plate is walked onto a delivery square. Its step graph:

    prepare item k (chop / blend)  ──>  plate item k  ──┐
    ...                                                 ├──>  deliver
    prepare item K                 ──>  plate item K  ──┘

| recipe               | items on the plate               | steps (prepare + plate + deliver) |
|----------------------|----------------------------------|-----------------------------------|
| `ChoppedTomato`      | chopped tomato                   | 3                                 |
| `TomatoLettuceSalad` | chopped tomato, chopped lettuce  | 5                                 |
| `CarrotBanana`       | chopped carrot, chopped banana   | 5                                 |
| `OnionSoup`          | blended onion, blended tomato    | 5                                 |
| `BananaSmoothie`     | blended banana                   | 3                                 |

The order of `RECIPES` is the goal index used in `recipes_BN` arrays. Items are encoded as
`code = kind * 3 + state` (15 codes); a *bag* is a count vector over the codes.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

INGREDIENTS: tuple[str, ...] = ("tomato", "lettuce", "onion", "carrot", "banana")
PLATE = len(INGREDIENTS)
OBJECT_KINDS: tuple[str, ...] = (*INGREDIENTS, "plate")
RAW, CHOPPED, BLENDED = 0, 1, 2
STATE_NAMES: tuple[str, ...] = ("raw", "chopped", "blended")
N_CODES = len(INGREDIENTS) * len(STATE_NAMES)


def item_code(kind: int, state: int) -> int:
    """Code of an (ingredient kind, processing state) item, 0..14."""
    return kind * len(STATE_NAMES) + state


class Recipe(NamedTuple):
    name: str
    items: tuple[tuple[int, int], ...]  # (ingredient kind, state), distinct

    def item_names(self) -> list[str]:
        return [f"{STATE_NAMES[s]} {INGREDIENTS[k]}" for k, s in self.items]

    def step_names(self) -> list[str]:
        """Names of the recipe graph's steps, in the order of `RecipeProgress` fields."""
        names = self.item_names()
        return [f"prepare {n}" for n in names] + [f"plate {n}" for n in names] + ["deliver"]


RECIPES: tuple[Recipe, ...] = (
    Recipe("ChoppedTomato", ((0, CHOPPED),)),
    Recipe("TomatoLettuceSalad", ((0, CHOPPED), (1, CHOPPED))),
    Recipe("CarrotBanana", ((3, CHOPPED), (4, CHOPPED))),
    Recipe("OnionSoup", ((2, BLENDED), (0, BLENDED))),
    Recipe("BananaSmoothie", ((4, BLENDED),)),
)
RECIPE_NAMES: tuple[str, ...] = tuple(r.name for r in RECIPES)
MAX_ITEMS = max(len(r.items) for r in RECIPES)

# RECIPE_ITEM_CODES_RK[r, k]: code of item k of recipe r, -1 past its last item.
RECIPE_ITEM_CODES_RK = np.full((len(RECIPES), MAX_ITEMS), -1, dtype=np.int64)
# RECIPE_BAGS_RC[r]: the exact bag of a plate that serves recipe r.
RECIPE_BAGS_RC = np.zeros((len(RECIPES), N_CODES), dtype=np.int64)
for _r, _recipe in enumerate(RECIPES):
    assert len(set(_recipe.items)) == len(_recipe.items), "recipe items must be distinct"
    for _k, (_kind, _state) in enumerate(_recipe.items):
        RECIPE_ITEM_CODES_RK[_r, _k] = item_code(_kind, _state)
        RECIPE_BAGS_RC[_r, item_code(_kind, _state)] = 1
RECIPE_ITEM_CODES_RK.setflags(write=False)
RECIPE_BAGS_RC.setflags(write=False)


def recipe_index(name: str, field: str = "recipe") -> int:
    """Index of recipe `name` in `RECIPES`, or a ValueError naming the field."""
    try:
        return RECIPE_NAMES.index(name)
    except ValueError:
        raise ValueError(
            f"{field}: unknown recipe {name!r} (expected one of {', '.join(RECIPE_NAMES)})"
        ) from None


def recipe_indices(recipes: Sequence[str] | np.ndarray, field: str = "recipes") -> np.ndarray:
    """Recipe indices from names or indices, any shape; validated."""
    array = np.asarray(recipes)
    if array.dtype.kind in "USO":
        flat = [recipe_index(str(n), field) for n in array.reshape(-1)]
        return np.array(flat, dtype=np.int64).reshape(array.shape)
    if array.dtype.kind not in "iu":
        raise ValueError(f"{field}: expected recipe names or indices, got dtype {array.dtype}")
    if array.size and (array.min() < 0 or array.max() >= len(RECIPES)):
        raise ValueError(f"{field}: expected recipe indices in 0..{len(RECIPES) - 1}")
    return array.astype(np.int64)
