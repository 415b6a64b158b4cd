"""Training-only reward shaping in the kitchen: spoiled ingredients.

Nothing comes off a plate in the kitchen, so one careless step can make a dish impossible: a
cook holding a plate with a chopped carrot walks into the raw banana and scoops it (a raw
ingredient on a plate can never be chopped). The +20 of the dish is then lost for good, but the
learner only finds out by value propagation from dishes it has not yet learned to cook; until
then spoiling costs nothing (the sub-goal reward keeps what was earned), spoiled kitchens fill
the replay, and learning stalls. Failed CarrotBanana networks had spoiled their only plate in
about half of their gate episodes by the end.

`wasted_items` counts, for every cook, the ingredients its recipe needs that lie on a plate that
can never be served to it: the item is in a state the recipe does not take (raw, or blended
where chopped is wanted), or the plate holds an item the recipe does not take. The training
kitchens (`trainer.cooking.kitchens`) charge `CookingConfig.spoil_penalty` per newly wasted item,
at the step it happens. It is a training reward only: gates, curves and the evaluation count
dishes (+20) and waiting steps (-0.01), never this.

Tried and dropped (`reports/cooking/README.md`): potential-based sub-goal shaping, Φ(s') - Φ(s)
with Φ the recipe steps done (1 of 5 CarrotBanana seeds passed, about half without it); a -1
penalty for a step into something that did nothing (a "bump"), meant to separate such steps
from useful ones in the task Q-vector: it slowed CarrotBanana (2 of 15 seeds had learned the
dish after 36 000 steps, 4 of 5 without it) and the salad network failed its gate (0 %).
"""

from __future__ import annotations

import functools

import numpy as np

from envs.cooking.layouts import Layout
from envs.cooking.recipes import PLATE, RECIPE_BAGS_RC, RECIPES
from envs.cooking.world import CookingState, item_codes, plate_bags

# RECIPE_KINDS_RK[r, kind]: recipe r needs an ingredient of this kind (plates: never)
RECIPE_KINDS_RK = np.zeros((len(RECIPES), PLATE + 1), dtype=bool)
for _r, _recipe in enumerate(RECIPES):
    for _kind, _state in _recipe.items:
        RECIPE_KINDS_RK[_r, _kind] = True
RECIPE_KINDS_RK.setflags(write=False)


@functools.lru_cache(maxsize=64)
def _plate_slots(layout: Layout) -> np.ndarray:
    """(O,) the slot of each plate object among the layout's plates, -1 for ingredients."""
    plates_P = np.flatnonzero(layout.object_kinds_O == PLATE)
    slots_O = np.full(len(layout.object_kinds_O), -1, dtype=np.int64)
    slots_O[plates_P] = np.arange(len(plates_P))
    return slots_O


def wasted_items(layout: Layout, state: CookingState, recipes_BN: np.ndarray) -> np.ndarray:
    """(B, N) ingredients each cook's recipe needs that lie on a plate it can never serve.

    `recipes_BN`: recipe indices (as `BatchedCookingWorld.recipes`)."""
    codes_BO = item_codes(layout, state)  # -1: plates and gone objects
    bags_BPC = plate_bags(layout, state)
    if bags_BPC.shape[1] == 0:
        return np.zeros(recipes_BN.shape, dtype=np.int64)
    recipe_bags_BNC = RECIPE_BAGS_RC[recipes_BN]
    clean_BNP = np.all(bags_BPC[:, None, :, :] <= recipe_bags_BNC[:, :, None, :], axis=-1)
    plated_BO = (state.obj_plate >= 0) & (codes_BO >= 0)
    needed_BNO = RECIPE_KINDS_RK[recipes_BN][:, :, layout.object_kinds_O] & plated_BO[:, None]
    code_BNO = np.broadcast_to(np.maximum(codes_BO, 0)[:, None, :], needed_BNO.shape)
    wanted_BNO = np.take_along_axis(recipe_bags_BNC, code_BNO, axis=-1) > 0
    slot_BNO = np.broadcast_to(
        _plate_slots(layout)[np.maximum(state.obj_plate, 0)][:, None, :], needed_BNO.shape
    )
    clean_BNO = np.take_along_axis(clean_BNP, slot_BNO, axis=-1)
    return np.sum(needed_BNO & ~(wanted_BNO & clean_BNO), axis=-1)
