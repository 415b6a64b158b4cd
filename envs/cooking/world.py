"""The rules of the cooking world as pure numpy functions over a batch of B kitchens of one layout.

Both the PettingZoo env (B = 1) and the batched simulator step through `step_state`, so there is
one implementation of the rules.

| action | meaning | (Δrow, Δcol) |
|--------|---------|--------------|
| 0      | stay    | (0, 0)       |
| 1      | up      | (-1, 0)      |
| 2      | down    | (+1, 0)      |
| 3      | left    | (0, -1)      |
| 4      | right   | (0, +1)      |

Every agent acts at once. A move into a floor cell succeeds unless another agent stands there at
the start of the step or another agent moves into the same cell (then neither moves; a swap is
blocked by the first rule, and so is following an agent that leaves). A move into a wall does
nothing. A move into a counter or station *interacts* with it and the agent stays where it is;
two agents interacting with the same cell in one step both fail (like colliding moves).

Interaction with cell T, holding h (or nothing), item x lying on T (or nothing):

| hands | on T                 | T is            | effect                                        |
|-------|----------------------|-----------------|-----------------------------------------------|
| empty | raw ingredient       | cutting board   | chop it (one interaction; it stays on board)  |
| empty | raw ingredient       | blender         | blend it (one interaction; stays in blender)  |
| empty | any other item       | any             | pick it up (a plate with all its contents)    |
| h     | nothing              | counter         | put h down                                    |
| h     | nothing              | board / blender | put h down if h is a lone ingredient          |
| plate | (always empty)       | delivery square | deliver, if the contents are exactly an       |
|       |                      |                 | undelivered agent's recipe (else nothing)     |
| ingr. | plate                | counter         | put the ingredient onto the plate             |
| plate | lone ingredient      | any             | scoop the ingredient onto the held plate      |
| other combinations                             | nothing                                       |

A raw ingredient on a board or in a blender can only be processed, not picked up raw. Nothing
can be taken off a plate. A delivered dish is credited to the delivering agent if it is that
agent's recipe, else to the lowest-index agent still waiting for that recipe; the plate and its
contents leave the world. Simultaneous deliveries are credited in agent order.

Reward of agent i for the transition: +`DISH_REWARD` when a dish is credited to i, −`TIME_PENALTY`
on every step that starts with i's dish undelivered, plus optional sub-goal rewards computed by
the batched world from `recipe_progress` (paper §4.3: 20 per dish, 0.01 per step).
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import numpy as np

from envs.cooking.layouts import BLENDER, BOARD, COUNTER, DELIVERY, FLOOR, WALL, Layout
from envs.cooking.recipes import (
    BLENDED,
    CHOPPED,
    N_CODES,
    PLATE,
    RAW,
    RECIPE_BAGS_RC,
    RECIPE_ITEM_CODES_RK,
    STATE_NAMES,
)

ACTION_MEANINGS: tuple[str, ...] = ("stay", "up", "down", "left", "right")
ACTION_DELTAS_A2 = np.array([[0, 0], [-1, 0], [1, 0], [0, -1], [0, 1]], dtype=np.int64)
N_ACTIONS = len(ACTION_MEANINGS)
DISH_REWARD = 20.0
TIME_PENALTY = 0.01


class CookingState(NamedTuple):
    """Dynamic state of B kitchens; objects are the layout's, in reading order."""

    agent_rc: np.ndarray  # (B, N, 2) int64 row, column
    obj_rc: np.ndarray  # (B, O, 2) int64: the holder's / plate's cell while held / plated
    obj_holder: np.ndarray  # (B, O) int64 agent holding it, -1 none
    obj_plate: np.ndarray  # (B, O) int64 plate object it lies on, -1 none
    obj_state: np.ndarray  # (B, O) int64 RAW / CHOPPED / BLENDED (plates: RAW)
    obj_gone: np.ndarray  # (B, O) bool: delivered, out of the world
    delivered: np.ndarray  # (B, N) bool: the agent's dish has been credited

    def copy(self) -> CookingState:
        return CookingState(*(a.copy() for a in self))

    def select(self, index: np.ndarray | slice | int) -> CookingState:
        """The kitchens at `index` along the batch axis (copies)."""
        picked = [np.asarray(a[index]) for a in self]
        if picked[0].ndim == 2:  # an int index dropped the batch axis: keep it
            picked = [p[None] for p in picked]
        return CookingState(*(p.copy() for p in picked))


def start_states(
    layout: Layout, n_envs: int, rng: np.random.Generator | None = None
) -> CookingState:
    """The layout's start state for `n_envs` kitchens. With `rng`, every agent starts instead on
    a random floor cell of the area its layout start lies in (distinct cells)."""
    n, o = layout.n_agents, layout.n_objects
    agent_rc = np.broadcast_to(layout.agent_starts_N2, (n_envs, n, 2)).copy()
    if rng is not None:
        for b in range(n_envs):
            taken: set[tuple[int, int]] = set()
            for i, (r, c) in enumerate(layout.agent_starts_N2.tolist()):
                area = np.argwhere(layout.floor_region_HW == layout.floor_region_HW[r, c])
                free = [tuple(p) for p in area.tolist() if tuple(p) not in taken]
                agent_rc[b, i] = free[int(rng.integers(len(free)))]
                taken.add((int(agent_rc[b, i, 0]), int(agent_rc[b, i, 1])))
    return CookingState(
        agent_rc=agent_rc,
        obj_rc=np.broadcast_to(layout.object_starts_O2, (n_envs, o, 2)).copy(),
        obj_holder=np.full((n_envs, o), -1, dtype=np.int64),
        obj_plate=np.full((n_envs, o), -1, dtype=np.int64),
        obj_state=np.full((n_envs, o), RAW, dtype=np.int64),
        obj_gone=np.zeros((n_envs, o), dtype=bool),
        delivered=np.zeros((n_envs, n), dtype=bool),
    )


def cell_kinds(layout: Layout, rc_X2: np.ndarray) -> np.ndarray:
    """Cell kind at each (row, col); cells outside the grid are walls."""
    height, width = layout.cells_HW.shape
    r, c = rc_X2[..., 0], rc_X2[..., 1]
    inside = (r >= 0) & (r < height) & (c >= 0) & (c < width)
    kinds = layout.cells_HW[np.clip(r, 0, height - 1), np.clip(c, 0, width - 1)]
    return np.where(inside, kinds, WALL)


@functools.cache
def _not_self(n_agents: int) -> np.ndarray:
    return ~np.eye(n_agents, dtype=bool)


def item_codes(layout: Layout, state: CookingState) -> np.ndarray:
    """(B, O) item code of every ingredient still in the world; -1 for plates and gone objects."""
    codes = layout.object_kinds_O * len(STATE_NAMES) + state.obj_state
    return np.where((layout.object_kinds_O == PLATE) | state.obj_gone, -1, codes)


def plate_bags(layout: Layout, state: CookingState) -> np.ndarray:
    """(B, P, 15) bag of every plate of the layout (P = its plates, in object order)."""
    plates_P = np.flatnonzero(layout.object_kinds_O == PLATE)
    codes_BO = item_codes(layout, state)
    onehot_BOC = codes_BO[..., None] == np.arange(N_CODES)
    on_BOP = state.obj_plate[..., None] == plates_P
    return np.einsum("bop,boc->bpc", on_BOP.astype(np.int64), onehot_BOC.astype(np.int64))


def step_state(
    layout: Layout, state: CookingState, actions_BN: np.ndarray, recipes_BN: np.ndarray
) -> tuple[CookingState, np.ndarray]:
    """One simultaneous step of every kitchen. Returns (next state, served_BN: dish credited)."""
    s = state.copy()
    n_agents = actions_BN.shape[1]
    target_BN2 = s.agent_rc + ACTION_DELTAS_A2[actions_BN]
    kind_BN = cell_kinds(layout, target_BN2)
    acting_BN = actions_BN != 0
    moving_BN = acting_BN & (kind_BN == FLOOR)
    interacting_BN = acting_BN & (kind_BN != FLOOR) & (kind_BN != WALL)

    not_self = _not_self(n_agents)
    same_target_BNN = np.all(target_BN2[:, :, None] == target_BN2[:, None, :], -1) & not_self
    onto_agent_BN = np.any(
        np.all(target_BN2[:, :, None] == s.agent_rc[:, None, :], -1) & not_self, -1
    )
    clash_BN = np.any(same_target_BNN & moving_BN[:, None, :], -1)
    moves_BN = moving_BN & ~clash_BN & ~onto_agent_BN
    s.agent_rc[moves_BN] = target_BN2[moves_BN]
    interacting_BN &= ~np.any(same_target_BNN & interacting_BN[:, None, :], -1)

    served_BN = np.zeros(s.delivered.shape, dtype=bool)
    # Interactions of different agents touch different cells and different held items, so
    # handling them one agent after the other equals handling them at once (except the
    # documented agent-order crediting of simultaneous deliveries).
    for n in range(n_agents):
        envs_E = np.flatnonzero(interacting_BN[:, n])
        if envs_E.size:
            cells = (target_BN2[envs_E, n], kind_BN[envs_E, n])
            _interact(layout, s, envs_E, n, *cells, recipes_BN, served_BN)
    carry_along(s)
    return s, served_BN


def _interact(
    layout: Layout,
    s: CookingState,
    envs_E: np.ndarray,
    n: int,
    target_E2: np.ndarray,
    kind_E: np.ndarray,
    recipes_BN: np.ndarray,
    served_BN: np.ndarray,
) -> None:
    """Agent n interacts with cell target_E2 in kitchens envs_E (mutates `s`)."""
    if layout.n_objects == 0:
        return  # an empty kitchen: nothing to pick up, process or deliver
    lone_EO = (s.obj_holder[envs_E] < 0) & (s.obj_plate[envs_E] < 0) & ~s.obj_gone[envs_E]
    on_target_EO = lone_EO & np.all(s.obj_rc[envs_E] == target_E2[:, None, :], -1)
    has_top_E, top_E = on_target_EO.any(1), on_target_EO.argmax(1)
    held_EO = s.obj_holder[envs_E] == n
    has_held_E, held_E = held_EO.any(1), held_EO.argmax(1)
    top_plate_E = has_top_E & (layout.object_kinds_O[top_E] == PLATE)
    top_ingredient_E = has_top_E & ~top_plate_E
    held_plate_E = has_held_E & (layout.object_kinds_O[held_E] == PLATE)
    held_ingredient_E = has_held_E & ~held_plate_E
    tool_E = (kind_E == BOARD) | (kind_E == BLENDER)

    raw_top_E = top_ingredient_E & (s.obj_state[envs_E, top_E] == RAW)
    chop_E = ~has_held_E & raw_top_E & (kind_E == BOARD)
    blend_E = ~has_held_E & raw_top_E & (kind_E == BLENDER)
    pick_E = ~has_held_E & has_top_E & ~chop_E & ~blend_E
    accepts_E = (kind_E == COUNTER) | (held_ingredient_E & tool_E)
    put_E = has_held_E & ~has_top_E & accepts_E
    onto_plate_E = held_ingredient_E & top_plate_E
    scoop_E = held_plate_E & top_ingredient_E
    deliver_E = held_plate_E & (kind_E == DELIVERY)

    s.obj_state[envs_E[chop_E], top_E[chop_E]] = CHOPPED
    s.obj_state[envs_E[blend_E], top_E[blend_E]] = BLENDED
    s.obj_holder[envs_E[pick_E], top_E[pick_E]] = n
    s.obj_holder[envs_E[put_E], held_E[put_E]] = -1
    s.obj_rc[envs_E[put_E], held_E[put_E]] = target_E2[put_E]
    s.obj_holder[envs_E[onto_plate_E], held_E[onto_plate_E]] = -1
    s.obj_plate[envs_E[onto_plate_E], held_E[onto_plate_E]] = top_E[onto_plate_E]
    s.obj_plate[envs_E[scoop_E], top_E[scoop_E]] = held_E[scoop_E]
    if deliver_E.any():
        _deliver(layout, s, envs_E[deliver_E], n, held_E[deliver_E], recipes_BN, served_BN)


def _deliver(
    layout: Layout,
    s: CookingState,
    envs_D: np.ndarray,
    n: int,
    plate_D: np.ndarray,
    recipes_BN: np.ndarray,
    served_BN: np.ndarray,
) -> None:
    """Agent n walks plate_D onto a delivery square; credit the dish or refuse it."""
    codes_DO = item_codes(layout, s.select(envs_D))
    on_plate_DO = s.obj_plate[envs_D] == plate_D[:, None]
    bag_DC = np.sum((codes_DO[..., None] == np.arange(N_CODES)) & on_plate_DO[..., None], axis=1)
    wants_DN = np.all(RECIPE_BAGS_RC[recipes_BN[envs_D]] == bag_DC[:, None, :], -1)
    wants_DN &= ~s.delivered[envs_D]
    credited_D = np.where(wants_DN[:, n], n, wants_DN.argmax(1))  # deliverer first
    ok_D = wants_DN.any(1)
    envs, plate, agent = envs_D[ok_D], plate_D[ok_D], credited_D[ok_D]
    s.delivered[envs, agent] = True
    served_BN[envs, agent] = True
    leaving_DO = on_plate_DO[ok_D] | (np.arange(layout.n_objects) == plate[:, None])
    s.obj_gone[envs] |= leaving_DO
    s.obj_holder[envs, plate] = -1


def carry_along(s: CookingState) -> None:
    """Held objects sit at their holder's cell, plated ones at their plate's (plates first)."""
    held_b, held_o = np.nonzero(s.obj_holder >= 0)
    s.obj_rc[held_b, held_o] = s.agent_rc[held_b, s.obj_holder[held_b, held_o]]
    plated_b, plated_o = np.nonzero((s.obj_plate >= 0) & ~s.obj_gone)
    s.obj_rc[plated_b, plated_o] = s.obj_rc[plated_b, s.obj_plate[plated_b, plated_o]]


class RecipeProgress(NamedTuple):
    """Which steps of each agent's recipe graph are done (padded items are False)."""

    prepared_BNK: np.ndarray  # an ingredient in item k's state exists in the world
    plated_BNK: np.ndarray  # item k lies on the agent's best plate (see `recipe_progress`)
    delivered_BN: np.ndarray

    @property
    def count_BN(self) -> np.ndarray:
        """Steps done before delivery: prepared + plated items."""
        return self.prepared_BNK.sum(-1) + self.plated_BNK.sum(-1)


def recipe_progress(layout: Layout, state: CookingState, recipes_BN: np.ndarray) -> RecipeProgress:
    """Progress of every agent's recipe. The *best plate* of a recipe is the plate holding the most
    of its items among plates holding nothing else (ties: the first plate of the layout)."""
    items_BNK = RECIPE_ITEM_CODES_RK[recipes_BN]
    valid_BNK = items_BNK >= 0
    safe_BNK = np.maximum(items_BNK, 0)
    codes_BO = item_codes(layout, state)
    world_bag_BC = np.sum(codes_BO[..., None] == np.arange(N_CODES), axis=1)
    prepared_BNK = valid_BNK & (np.take_along_axis(world_bag_BC[:, None, :], safe_BNK, -1) > 0)

    bags_BPC = plate_bags(layout, state)
    if bags_BPC.shape[1] == 0:
        plated_BNK = np.zeros_like(prepared_BNK)
    else:
        recipe_bags_BNC = RECIPE_BAGS_RC[recipes_BN]
        clean_BNP = np.all(bags_BPC[:, None, :, :] <= recipe_bags_BNC[:, :, None, :], -1)
        on_best_BNP = np.where(clean_BNP, bags_BPC.sum(-1)[:, None, :], -1)
        best_BN = on_best_BNP.argmax(-1)
        best_bag_BNC = np.take_along_axis(bags_BPC, best_BN[..., None], axis=1)
        best_ok_BN = np.take_along_axis(clean_BNP, best_BN[..., None], -1)[..., 0]
        plated_BNK = valid_BNK & best_ok_BN[..., None]
        plated_BNK &= np.take_along_axis(best_bag_BNC, safe_BNK, -1) > 0
    return RecipeProgress(prepared_BNK, plated_BNK, state.delivered.copy())
