"""Observations of the cooking world: one fixed-length float32 vector per agent, the same length
for every layout, and the perspective transform between agents (paper §3.2, §4.3).

The vector is a sequence of blocks. Every block starts with the same five features

    present, x, y, rel_x, rel_y

with `x = column / 16`, `y = row / 16` (absolute, 16 = the largest layout side) and `rel = x - x_ego`,
`y - y_ego` relative to the observing agent (both times `present`; an absent slot is all zeros).

| block (in order)                   | count | features after the common five      | size |
|------------------------------------|-------|-------------------------------------|------|
| `self`, `other1` .. `other{N-1}`   | N     | holds_tomato .. holds_banana,       | 12   |
|   (agents; others in agent order)  |       | holds_plate (one-hot, 0 = nothing), |      |
|                                    |       | served (the agent's dish is done)   |      |
| `tomato0`, `tomato1`, `lettuce0`,  | 10    | chopped, blended, held, on_plate    | 9    |
|   .. `banana1` (ingredient slots)  |       |                                     |      |
| `plate0` .. `plate3`               | 4     | held, n_tomato .. n_banana (counts  | 11   |
|                                    |       | of each ingredient on the plate)    |      |
| `cutting_board0/1`, `blender0/1`,  | 6     | (none)                              | 5    |
|   `delivery0/1` (stations)         |       |                                     |      |

Length: 12 N + 164 (188 for two agents). Slots are filled in the layout's reading order; a held or
plated object is at its holder's / plate's cell; delivered objects and missing slots are absent.
The agent's own recipe and its progress are *not* observed (one network per goal); whether its
dish has been served is (`served`): after it, no action changes the cook's own return, which the
task network must learn (its Q is flat there, eq. 9 then hands over to the impact network) and
AAIL-B reads (`envs.cooking.domain.CookingDomain.goal_reached`).

Perspective: absolute coordinates are multiples of 1/16, exact in float32, so agent j's view is
computed exactly from the ego's: move j's block to the front and recompute every `rel` from the
absolute positions. The env computes its observations with the same function (`_fill_relative`),
so `perspective(obs_of_ego, N, j)` equals the env's observation of agent j bit for bit.
"""

from __future__ import annotations

import functools

import numpy as np

from envs.cooking.layouts import (
    CELL_NAMES,
    MAX_PER_INGREDIENT,
    MAX_PER_STATION,
    MAX_PLATES,
    STATION_KINDS,
    Layout,
)
from envs.cooking.recipes import BLENDED, CHOPPED, INGREDIENTS, OBJECT_KINDS, PLATE
from envs.cooking.world import CookingState

COORD_SCALE = 16.0
COMMON = ("present", "x", "y", "rel_x", "rel_y")
AGENT_FEATURES = (*COMMON, *(f"holds_{k}" for k in OBJECT_KINDS), "served")
INGREDIENT_FEATURES = (*COMMON, "chopped", "blended", "held", "on_plate")
PLATE_FEATURES = (*COMMON, "held", *(f"n_{k}" for k in INGREDIENTS))
STATION_FEATURES = COMMON
AGENT_DIM = len(AGENT_FEATURES)
SERVED = AGENT_FEATURES.index("served")

SHARED_BLOCKS: tuple[tuple[str, tuple[str, ...]], ...] = (
    *((f"{k}{i}", INGREDIENT_FEATURES) for k in INGREDIENTS for i in range(MAX_PER_INGREDIENT)),
    *((f"plate{i}", PLATE_FEATURES) for i in range(MAX_PLATES)),
    *(
        (f"{CELL_NAMES[s]}{i}", STATION_FEATURES)
        for s in STATION_KINDS
        for i in range(MAX_PER_STATION)
    ),
)
_SHARED_STARTS = np.cumsum([0] + [len(f) for _, f in SHARED_BLOCKS])
SHARED_DIM = int(_SHARED_STARTS[-1])
_SHARED_INDEX = {
    name: int(start) for (name, _), start in zip(SHARED_BLOCKS, _SHARED_STARTS, strict=False)
}


def obs_dim(n_agents: int) -> int:
    return AGENT_DIM * n_agents + SHARED_DIM


def feature_names(n_agents: int) -> list[str]:
    owners = ["self"] + [f"other{j}" for j in range(1, n_agents)]
    names = [f"{o}.{f}" for o in owners for f in AGENT_FEATURES]
    return names + [f"{block}.{f}" for block, features in SHARED_BLOCKS for f in features]


def observation_bounds(n_agents: int) -> tuple[np.ndarray, np.ndarray]:
    """Per-feature (low, high): rel in [-1, 1], counts in [0, 2], everything else in [0, 1]."""
    names = feature_names(n_agents)
    low = np.array([-1.0 if ".rel_" in n else 0.0 for n in names], dtype=np.float32)
    high = np.array([MAX_PER_INGREDIENT if ".n_" in n else 1.0 for n in names], dtype=np.float32)
    return low, high


@functools.cache
def _block_starts(n_agents: int) -> np.ndarray:
    agents = np.arange(n_agents) * AGENT_DIM
    return np.concatenate([agents, AGENT_DIM * n_agents + _SHARED_STARTS[:-1]]).astype(np.int64)


def _fill_relative(obs_BD: np.ndarray, n_agents: int) -> np.ndarray:
    """Recompute every block's rel_x, rel_y from the absolute positions (in place; float32)."""
    starts = _block_starts(n_agents)
    present = obs_BD[..., starts]
    obs_BD[..., starts + 3] = present * (obs_BD[..., starts + 1] - obs_BD[..., 1:2])
    obs_BD[..., starts + 4] = present * (obs_BD[..., starts + 2] - obs_BD[..., 2:3])
    return obs_BD


class _Plan:
    """Where a layout's objects and stations go in the shared part of the vector."""

    def __init__(self, layout: Layout) -> None:
        kinds = layout.object_kinds_O
        self.ingredients = np.flatnonzero(kinds != PLATE)
        self.plates = np.flatnonzero(kinds == PLATE)
        seen: dict[int, int] = {}
        slots = []
        for o in self.ingredients.tolist():
            k = int(kinds[o])
            slots.append(_SHARED_INDEX[f"{INGREDIENTS[k]}{seen.get(k, 0)}"])
            seen[k] = seen.get(k, 0) + 1
        ingredient_starts = np.array(slots, dtype=np.int64)
        plate_starts = np.array([_SHARED_INDEX[f"plate{i}"] for i in range(len(self.plates))])
        self.ingredient_cols = (ingredient_starts[:, None] + np.arange(9)).reshape(-1)
        self.plate_cols = (plate_starts[:, None].astype(np.int64) + np.arange(11)).reshape(-1)
        self.stations = np.zeros(SHARED_DIM, dtype=np.float32)
        for s in STATION_KINDS:
            for i, (r, c) in enumerate(layout.stations[s].tolist()):
                start = _SHARED_INDEX[f"{CELL_NAMES[s]}{i}"]
                self.stations[start : start + 3] = (1.0, c / COORD_SCALE, r / COORD_SCALE)
        self.kinds = kinds


@functools.lru_cache(maxsize=64)
def _plan(layout: Layout) -> _Plan:
    return _Plan(layout)


@functools.cache
def _observation_order(n_agents: int) -> np.ndarray:
    """(N, N): agent block order in each agent's observation (itself first, others in order)."""
    return np.array([[i] + [j for j in range(n_agents) if j != i] for i in range(n_agents)])


def _xy(rc_X2: np.ndarray) -> np.ndarray:
    return rc_X2[..., ::-1].astype(np.float32) / np.float32(COORD_SCALE)


def observations(layout: Layout, state: CookingState) -> np.ndarray:
    """Every agent's observation, shape (B, N, 12 N + 164), float32."""
    plan = _plan(layout)
    n_envs, n_agents = state.delivered.shape
    present_BO = (~state.obj_gone).astype(np.float32)
    xy_BO2 = _xy(state.obj_rc) * present_BO[..., None]
    held_BO = (state.obj_holder >= 0).astype(np.float32)

    shared = np.broadcast_to(plan.stations, (n_envs, SHARED_DIM)).copy()
    ing = plan.ingredients
    ing_BI9 = np.zeros((n_envs, ing.size, 9), dtype=np.float32)
    ing_BI9[..., 0] = present_BO[:, ing]
    ing_BI9[..., 1:3] = xy_BO2[:, ing]
    ing_BI9[..., 5] = state.obj_state[:, ing] == CHOPPED
    ing_BI9[..., 6] = state.obj_state[:, ing] == BLENDED
    ing_BI9[..., 7] = held_BO[:, ing]
    ing_BI9[..., 8] = state.obj_plate[:, ing] >= 0
    ing_BI9[..., 5:] *= present_BO[:, ing, None]
    shared[:, plan.ingredient_cols] = ing_BI9.reshape(n_envs, -1)

    pl = plan.plates
    if pl.size:
        plate_BP11 = np.zeros((n_envs, pl.size, 11), dtype=np.float32)
        plate_BP11[..., 0] = present_BO[:, pl]
        plate_BP11[..., 1:3] = xy_BO2[:, pl]
        plate_BP11[..., 5] = held_BO[:, pl] * present_BO[:, pl]
        on_BOP = (state.obj_plate[..., None] == pl) & ~state.obj_gone[..., None]
        kind_onehot_OK = (plan.kinds[:, None] == np.arange(len(INGREDIENTS))).astype(np.float32)
        plate_BP11[..., 6:] = np.einsum("bop,ok->bpk", on_BOP.astype(np.float32), kind_onehot_OK)
        shared[:, plan.plate_cols] = plate_BP11.reshape(n_envs, -1)

    agents_BNF = np.zeros((n_envs, n_agents, AGENT_DIM), dtype=np.float32)
    agents_BNF[..., 0] = 1.0
    agents_BNF[..., 1:3] = _xy(state.agent_rc)
    held_b, held_o = np.nonzero(state.obj_holder >= 0)
    agents_BNF[held_b, state.obj_holder[held_b, held_o], 5 + plan.kinds[held_o]] = 1.0
    agents_BNF[..., SERVED] = state.delivered

    ordered = agents_BNF[:, _observation_order(n_agents)].reshape(n_envs, n_agents, -1)
    obs_BND = np.concatenate(
        [ordered, np.broadcast_to(shared[:, None, :], (n_envs, n_agents, SHARED_DIM))], axis=-1
    )
    return _fill_relative(obs_BND, n_agents)


def _check_obs(obs_BD: np.ndarray, n_agents: int) -> np.ndarray:
    obs_BD = np.asarray(obs_BD, dtype=np.float32)
    if obs_BD.ndim < 1 or obs_BD.shape[-1] != obs_dim(n_agents):
        raise ValueError(
            f"obs: expected last dimension {obs_dim(n_agents)} for {n_agents} agents, "
            f"got shape {obs_BD.shape}"
        )
    return obs_BD


def select_agents(obs_BD: np.ndarray, n_agents: int, order: list[int]) -> np.ndarray:
    """The view holding the agent blocks `order` (first = the new ego) and every shared block,
    with rel features recomputed for the new ego. Exact (see the module docstring)."""
    obs_BD = _check_obs(obs_BD, n_agents)
    for i in order:
        if not 0 <= i < n_agents:
            raise ValueError(f"agent: expected 0..{n_agents - 1}, got {i}")
    blocks = obs_BD[..., : AGENT_DIM * n_agents].reshape(*obs_BD.shape[:-1], n_agents, AGENT_DIM)
    picked = blocks[..., order, :].reshape(*obs_BD.shape[:-1], len(order) * AGENT_DIM)
    view = np.concatenate([picked, obs_BD[..., AGENT_DIM * n_agents :]], axis=-1)
    return _fill_relative(view, len(order))


def perspective(obs_BD: np.ndarray, n_agents: int, i: int) -> np.ndarray:
    """Agent i's observation built from the ego's (i indexes the ego's layout; 0 = the ego)."""
    return select_agents(obs_BD, n_agents, [i] + [j for j in range(n_agents) if j != i])


def from_perspective(obs_BD: np.ndarray, n_agents: int, i: int) -> np.ndarray:
    """Inverse of `perspective`: the ego's observation back from agent i's view of it."""
    order = [i] + [j for j in range(n_agents) if j != i]
    return select_agents(obs_BD, n_agents, np.argsort(order).tolist())
