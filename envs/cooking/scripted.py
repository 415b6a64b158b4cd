"""Scripted cooks: a planner for every recipe and the hand-over helper of the coexistence layout.

A `ScriptedCook` looks at the state afresh every step (no memory), picks the cell it wants to
walk into next and walks there (`navigation`). Its plan for recipe R, first match wins:

| holding            | situation                                      | walks into                    |
|--------------------|------------------------------------------------|-------------------------------|
| plate              | the plate is exactly R                         | the nearest delivery square   |
| plate              | a missing item of R lies ready on a cell       | that cell (scoops it)         |
| plate              | otherwise                                      | the nearest empty counter     |
| ingredient         | it is a missing item and a usable plate lies   | that plate                    |
|                    | on a counter                                   |                               |
| ingredient         | it is raw and R wants it chopped / blended     | the nearest empty board /     |
|                    |                                                | blender                       |
| ingredient         | otherwise                                      | the nearest empty counter     |
| nothing            | a plate holding exactly R lies on a counter    | that plate (picks it up)      |
| nothing            | a missing item lies ready (e.g. on the board)  | that cell (picks it up)       |
| nothing            | a raw missing ingredient lies on its tool      | the tool (chops / blends)     |
| nothing            | a raw missing ingredient lies on a counter     | that counter (picks it up)    |

A *usable* plate lies on a counter and holds only items of R; the plate R is built on is the usable
plate holding the most items of R (ties: the nearest). Only cells the cook can reach count.

With `first="carrot"` the cook prepares that ingredient before the recipe's others: while it is
still raw (or not yet within reach) the other raw ingredients are left alone and the cook waits.
This gives the other order of a recipe (the trainer records both, `trainer.cooking.kitchens`).

With `handover="carrot"` the cook is also a *helper*: once its own dish is served (or at once with
`handover_first=True`, or when its own plan is stuck) it carries a carrot it can reach to an empty
counter that the partner can reach too, unless the partner can already reach one.

`scripted_actions` runs several cooks in a batch of kitchens and breaks ties between them: if two
cooks want to walk into the same cell, the higher-index one waits.
"""

from __future__ import annotations

import functools
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from envs.cooking.layouts import BLENDER, BOARD, COUNTER, DELIVERY, Layout
from envs.cooking.navigation import STAY, Cell, action_towards, can_reach, cost, nearest
from envs.cooking.recipes import BLENDED, CHOPPED, INGREDIENTS, PLATE, RAW, RECIPES, recipe_index
from envs.cooking.world import ACTION_DELTAS_A2, CookingState

Item = tuple[int, int]


@functools.lru_cache(maxsize=256)
def _cells_of(layout: Layout, cell_kind: int) -> list[Cell]:
    return [(int(r), int(c)) for r, c in np.argwhere(layout.cells_HW == cell_kind).tolist()]


class _Kitchen:
    """One kitchen of a batched state, read for planning."""

    def __init__(self, layout: Layout, state: CookingState, b: int) -> None:
        self.layout = layout
        self.kinds = layout.object_kinds_O.tolist()
        self.rc: list[Cell] = [(int(r), int(c)) for r, c in state.obj_rc[b].tolist()]
        self.holder = state.obj_holder[b].tolist()
        self.plate = state.obj_plate[b].tolist()
        self.item_state = state.obj_state[b].tolist()
        self.gone = state.obj_gone[b].tolist()
        self.agents: list[Cell] = [(int(r), int(c)) for r, c in state.agent_rc[b].tolist()]
        self.delivered = state.delivered[b].tolist()
        self.lone = [
            o
            for o in range(len(self.kinds))
            if self.holder[o] < 0 and self.plate[o] < 0 and not self.gone[o]
        ]
        self.occupied = {self.rc[o] for o in self.lone}

    def others(self, agent: int) -> frozenset[Cell]:
        return frozenset(c for i, c in enumerate(self.agents) if i != agent)

    def held_by(self, agent: int) -> int | None:
        return next((o for o, h in enumerate(self.holder) if h == agent), None)

    def item(self, o: int) -> Item:
        return (self.kinds[o], self.item_state[o])

    def bag(self, plate: int) -> Counter[Item]:
        on = [o for o, p in enumerate(self.plate) if p == plate and not self.gone[o]]
        return Counter(self.item(o) for o in on)

    def empty(self, cell_kind: int) -> list[Cell]:
        return [c for c in _cells_of(self.layout, cell_kind) if c not in self.occupied]

    def cell_kind(self, cell: Cell) -> int:
        return int(self.layout.cells_HW[cell])


@dataclass(frozen=True)
class ScriptedCook:
    """A scripted cook for one recipe, optionally handing an ingredient to a partner."""

    recipe: str
    handover: str | None = None
    partner: int = 1
    handover_first: bool = False
    first: str | None = None  # the ingredient this cook prepares first (module docstring)

    def __post_init__(self) -> None:
        recipe_index(self.recipe)
        for name, value in (("handover", self.handover), ("first", self.first)):
            if value is not None and value not in INGREDIENTS:
                raise ValueError(f"{name}: expected one of {', '.join(INGREDIENTS)}, got {value!r}")

    def __call__(self, env: Any, agent: int) -> int:
        """Partner-policy form for `CookingSingleAgentEnv`: act in `env.world`'s first kitchen."""
        return self.act(env.layout, env.world.state, 0, agent, blocked=None)

    def act(
        self, layout: Layout, state: CookingState, b: int, agent: int, blocked: set[Cell] | None
    ) -> int:
        """The action of `agent` in kitchen b; `blocked` defaults to the other agents' cells."""
        k = _Kitchen(layout, state, b)
        target = self._target(k, agent)
        if blocked is None:
            blocked = set(k.others(agent))
        return STAY if target is None else action_towards(layout, k.agents[agent], target, blocked)

    def target(self, layout: Layout, state: CookingState, b: int, agent: int) -> Cell | None:
        """The cell this cook wants to walk into next (None: nothing to do)."""
        return self._target(_Kitchen(layout, state, b), agent)

    def _target(self, k: _Kitchen, agent: int) -> Cell | None:
        help_now = self.handover is not None and not _handed_over(
            k, self.handover, agent, self.partner
        )
        if help_now and (self.handover_first or k.delivered[agent]):
            return _handover_target(k, agent, self.handover or "", self.partner)
        own = None if k.delivered[agent] else _recipe_target(k, agent, self.recipe, self.first)
        if own is None and help_now:
            return _handover_target(k, agent, self.handover or "", self.partner)
        return own


def _recipe_target(k: _Kitchen, agent: int, recipe: str, first: str | None) -> Cell | None:
    items = set(RECIPES[recipe_index(recipe)].items)
    me = k.agents[agent]

    def reachable(o: int) -> bool:
        return can_reach(k.layout, me, k.rc[o])

    def closest(objects: list[int]) -> int | None:
        cell = nearest(k.layout, me, k.others(agent), [k.rc[o] for o in objects])
        return None if cell is None else next(o for o in objects if k.rc[o] == cell)

    usable = [
        p
        for p in k.lone
        if k.kinds[p] == PLATE
        and reachable(p)
        and set(k.bag(p)) <= items
        and max(k.bag(p).values(), default=0) <= 1
    ]
    base = max(usable, key=lambda p: (len(k.bag(p)), -cost(k.layout, me, k.rc[p])), default=None)
    missing = items - set(k.bag(base)) if base is not None else set(items)
    ready = [o for o in k.lone if k.kinds[o] != PLATE and reachable(o)]
    put_down = nearest(k.layout, me, k.others(agent), k.empty(COUNTER))
    held = k.held_by(agent)

    if held is not None and k.kinds[held] == PLATE:
        bag = k.bag(held)
        if set(bag) == items and sum(bag.values()) == len(items):
            squares = [(int(r), int(c)) for r, c in k.layout.stations[DELIVERY].tolist()]
            return nearest(k.layout, me, k.others(agent), squares)
        wanted = items - set(bag) if set(bag) <= items else set()
        scoop = closest([o for o in ready if k.item(o) in wanted])
        return k.rc[scoop] if scoop is not None else put_down
    if held is not None:
        kind, state = k.item(held)
        plates = [p for p in usable if (kind, state) not in k.bag(p)]
        if (kind, state) in items and plates:
            best = max(plates, key=lambda p: (len(k.bag(p)), -cost(k.layout, me, k.rc[p])))
            return k.rc[best]
        for tool, processed in ((BOARD, CHOPPED), (BLENDER, BLENDED)):
            if state == RAW and (kind, processed) in items:
                spot = nearest(k.layout, me, k.others(agent), k.empty(tool))
                return spot if spot is not None else put_down
        return put_down

    complete = [p for p in usable if set(k.bag(p)) == items]
    if complete:
        return k.rc[complete[0]]
    pick = closest([o for o in ready if k.item(o) in missing])
    if pick is not None:
        return k.rc[pick]
    for tool, processed in ((BOARD, CHOPPED), (BLENDER, BLENDED)):
        on_tool = [
            o
            for o in ready
            if k.item(o)[1] == RAW
            and (k.kinds[o], processed) in missing
            and k.cell_kind(k.rc[o]) == tool
        ]
        if on_tool:
            return k.rc[on_tool[0]]
    raw = [
        o
        for o in ready
        if k.item_state[o] == RAW
        and k.cell_kind(k.rc[o]) == COUNTER
        and any((k.kinds[o], s) in missing for s in (CHOPPED, BLENDED))
    ]
    if first is not None:
        kind = INGREDIENTS.index(first)
        prepared = any(k.kinds[o] == kind and k.item_state[o] != RAW for o in range(len(k.kinds)))
        if not prepared and any(i_kind == kind for i_kind, _ in missing):
            raw = [o for o in raw if k.kinds[o] == kind]  # none within reach yet: wait
    found = closest(raw)
    return None if found is None else k.rc[found]


def _handed_over(k: _Kitchen, ingredient: str, helper: int, partner: int) -> bool:
    """Whether the partner holds, or can reach, one of the ingredient (or one was delivered)."""
    kind = INGREDIENTS.index(ingredient)
    for o, o_kind in enumerate(k.kinds):
        if o_kind != kind:
            continue
        if k.gone[o] or k.holder[o] == partner:
            return True
        if k.holder[o] != helper and can_reach(k.layout, k.agents[partner], k.rc[o]):
            return True
    return False


def _handover_target(k: _Kitchen, agent: int, ingredient: str, partner: int) -> Cell | None:
    kind = INGREDIENTS.index(ingredient)
    me, partner_rc = k.agents[agent], k.agents[partner]
    counters = k.empty(COUNTER)
    shared = [c for c in counters if can_reach(k.layout, partner_rc, c)]
    held = k.held_by(agent)
    if held is not None and k.kinds[held] == kind:
        return nearest(k.layout, me, k.others(agent), shared)
    if held is not None:  # free the hands, away from the counters the partner can use
        private = [c for c in counters if c not in shared]
        return nearest(k.layout, me, k.others(agent), private or counters)
    mine = [o for o in k.lone if k.kinds[o] == kind and can_reach(k.layout, me, k.rc[o])]
    return nearest(k.layout, me, k.others(agent), [k.rc[o] for o in mine])


def scripted_actions(
    layout: Layout, state: CookingState, cooks: Sequence[ScriptedCook | None]
) -> np.ndarray:
    """Actions (B, N) of scripted cooks (None: the agent stays), with ties broken by index."""
    n_envs, n_agents = state.delivered.shape
    if len(cooks) != n_agents:
        raise ValueError(f"cooks: expected one per agent ({n_agents}), got {len(cooks)}")
    actions = np.zeros((n_envs, n_agents), dtype=np.int64)
    for b in range(n_envs):
        agents = [tuple(rc) for rc in state.agent_rc[b].tolist()]
        wanted: set[tuple[int, int]] = set()
        for i, cook in enumerate(cooks):
            if cook is None:
                continue
            blocked = {c for j, c in enumerate(agents) if j != i}
            action = cook.act(layout, state, b, i, blocked)
            delta = ACTION_DELTAS_A2[action]
            into = (agents[i][0] + int(delta[0]), agents[i][1] + int(delta[1]))
            if action != STAY and into in wanted:
                action = STAY  # a lower-index cook already walks into that cell this step
            wanted.add(into)
            actions[b, i] = action
    return actions
