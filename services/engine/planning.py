"""What a request's shape fixes, worked out once and remembered in `PlanCache`: the networks it
needs (`plan_members`), where each partner's rows lie among the members of their stacked group
(`layout_of`), and from the layout each member's input rows (`member_inputs`) and each
partner's impact Q-values (`impact_q`).

Member input rows (B observation rows, K task views, U_g partners with goal g):

| member          | input rows                                   | Q-values used as                   |
|-----------------|----------------------------------------------|------------------------------------|
| task            | (B*K, pair_dim), row b*K + k = view k of b   | mean over k -> q_task (B, A)       |
| impact, goal g  | (U_g*B, pair_dim), block u = the impact view | block u -> partner u's Q for g     |
|                 | of the u-th partner with goal g              |                                    |
| joint           | (B, obs_dim), the whole observation          | q (B, A)                           |

`PlanCache` is the engine's one memory of these (given to `InferenceEngine`, one per engine):
a bounded map whose keys name everything an entry depends on (the request's shape; a layout,
the (name, version) of its group's networks too). One rule makes an entry stale: it belongs to
the store generation it was made in (`ModelCache.generation`, moved by a refresh that saw the
store change), and a new generation starts from an empty map. A full map is emptied too.

| key                                                 | entry                            |
|-----------------------------------------------------|----------------------------------|
| ("members", env, method, ego goal, partners)        | `MemberPlan` (`plan_members`)    |
| ("seen", env, method, ego goal, partners)           | "seen", or "stacked" (the engine's|
|                                                     | goal-distribution rule)          |
| ("catalogue", env, method, ego goal, alias)         | `CataloguePlan`: every goal's    |
|                                                     | networks, whether one is missing |
| ("layout", group key, members, partners)            | `Layout` (`layout_of`)           |
| ("constant", shape, value, type)                    | a read-only filled array         |
"""

from __future__ import annotations

import bisect
import itertools
from collections.abc import Callable, Hashable, Sequence
from dataclasses import replace
from typing import Any, NamedTuple, TypeVar

import numpy as np

from model_store.errors import InvalidArgument
from model_store.naming import joint_model_name
from policy.belief_compiled import compiled_mix_goals
from services.engine.errors import InvalidRequest
from services.engine.messages import ActRequest, Member, ModelUsed
from services.engine.networks import MemberQ, StackedGroup
from services.engine.validation import CheckedPartner, CheckedRequest

V = TypeVar("V")

PLANS_MAX = 4096  # entries a `PlanCache` holds before it is emptied

Needs = tuple[tuple[str, str, str], ...]  # (model name, field to blame, why it is needed)
Slots = dict[tuple[int, str], tuple[int, int]]  # (partner position, goal) -> (member, block)


class Plans:
    """One store generation's entries (`PlanCache.at`): a dict emptied when full. Each
    operation is one dict operation, so threads share it without a lock (two threads that
    miss the same key both make the entry, equal by construction)."""

    def __init__(self, capacity: int, generation: int) -> None:
        self.capacity = capacity
        self.generation = generation
        self._entries: dict[Hashable, Any] = {}

    def get(self, key: Hashable) -> Any:
        """The entry of `key`, or None."""
        return self._entries.get(key)

    def put(self, key: Hashable, value: object) -> None:
        if len(self._entries) >= self.capacity:
            self._entries.clear()
        self._entries[key] = value

    def remember(self, key: Hashable, make: Callable[..., V], *args: Any) -> V:
        """The entry of `key`, made by `make(*args)` and kept when there is none."""
        value: V | None = self._entries.get(key)
        if value is None:
            value = make(*args)
            self.put(key, value)
        return value

    def __len__(self) -> int:
        return len(self._entries)


class PlanCache:
    """The engine's bounded memory of request plans and layouts (module docstring)."""

    def __init__(self, capacity: int = PLANS_MAX) -> None:
        if capacity < 1:
            raise ValueError(f"capacity: expected >= 1, got {capacity}")
        self.capacity = capacity
        self._plans = Plans(capacity, 0)

    def at(self, generation: int) -> Plans:
        """The entries of store generation `generation`: empty when it is not the last one
        asked for. A request holds the `Plans` it got, so an entry made from what an older
        generation served never lands among a newer one's."""
        plans = self._plans
        if plans.generation != generation:
            plans = self._plans = Plans(self.capacity, generation)
        return plans

    def __len__(self) -> int:
        return len(self._plans)


class MemberPlan(NamedTuple):
    """The networks a request needs: the members, and for each (model name, field to blame,
    why it is needed), in the same order."""

    members: tuple[Member, ...]
    needs: Needs


class CataloguePlan(NamedTuple):
    """The task network and every goal's impact network, and whether one of them was missing
    or could not be loaded in this store generation (then not tried again within it)."""

    members: tuple[Member, ...]
    needs: Needs
    missing: bool


def plan_members(request: ActRequest, checked: CheckedRequest) -> MemberPlan:
    """The networks a request needs: the task (or joint) network first, then the impact
    networks sorted by name (so that the order in which partners are listed does not change
    the stacked group)."""
    runtime = checked.runtime
    if request.method == "jl":
        goals = [
            request.ego_goal,
            *(p.goals[0] for p in sorted(checked.partners, key=lambda p: p.index)),
        ]
        try:
            name = joint_model_name(runtime.domain.name, goals[0], goals[1:])
        except InvalidArgument:  # a goal no model name can hold: there is no such network
            name = f"{runtime.domain.name}/joint/{'+'.join(goals)}"
        why = "jl needs the joint network of this goal combination"
        return MemberPlan((("joint", request.ego_goal),), ((name, "method", why),))
    members: list[Member] = [("task", request.ego_goal)]
    needs = [(runtime.task_names[request.ego_goal], "ego_goal", "no task network")]
    if request.method == "sl":
        return MemberPlan(tuple(members), tuple(needs))
    field_of: dict[str, str] = {}  # goal -> the first partner field that asks for it
    for i, partner in enumerate(checked.partners):
        suffix = "goal" if partner.probs is None else "goal_probs"
        for goal in partner.goals:
            field_of.setdefault(goal, f"partners[{i}].{suffix}")
    for goal in sorted(field_of, key=runtime.impact_names.__getitem__):
        needs.append((runtime.impact_names[goal], field_of[goal], "no impact network"))
        members.append(("impact", goal))
    return MemberPlan(tuple(members), tuple(needs))


def catalogue_plan(request: ActRequest, checked: CheckedRequest) -> CataloguePlan:
    """`plan_members` of the request with one partner given as a distribution over every
    goal of the environment: the task network and every goal's impact network."""
    goals = tuple(checked.runtime.domain.goals)
    every = CheckedPartner(0, goals, tuple(1.0 for _ in goals))
    members, needs = plan_members(request, replace(checked, partners=(every,)))
    return CataloguePlan(members, needs, missing=False)


def constant(plans: Plans, shape: tuple[int, ...], value: bool | float) -> np.ndarray:
    """A read-only array of `shape` filled with `value` (bool or float64), made once per shape
    and value: the blend's mask and temperatures are the same for every request of a shape,
    and building them took four numpy calls per act."""
    key = ("constant", shape, value, type(value))  # the type too: True == 1.0 as keys
    return plans.remember(key, _filled, shape, value)


def _filled(shape: tuple[int, ...], value: bool | float) -> np.ndarray:
    array = np.full(shape, value, dtype=bool if type(value) is bool else np.float64)
    array.flags.writeable = False
    return array


class Layout(NamedTuple):
    """What a request layout (members, partners' indices and goals) fixes, per stacked group."""

    # the impact members in order, as runs of consecutive members serving the same partners:
    # (the partners' positions, in order; how many members); one run for a belief's group,
    # whose members all take the same input rows
    position_runs: tuple[tuple[tuple[int, ...], int], ...]
    slots: Slots  # (partner position, goal) -> (member, block)
    models: tuple[ModelUsed, ...]  # the models used, the same objects on every call
    # the goal distributions' mixes (`impact_q`): per goal count, the partners' positions and
    # (P', G) rows of their goals' Q-values among the impact members' rows at batch 1 (member j
    # has one row per partner it serves; at batch B each row is B rows)
    mixes: tuple[tuple[tuple[int, ...], np.ndarray], ...]


def layout_of(checked: CheckedRequest, members: Sequence[Member], group: StackedGroup) -> Layout:
    """The layout of this request's partners over the group's members (with a belief over 35
    goals and 4 partners: 140 slots and 141 models)."""
    member_of = {goal: j for j, (role, goal) in enumerate(members) if role == "impact"}
    served: list[list[int]] = [[] for _ in members]
    slots: Slots = {}
    partners = checked.partners if len(members) > 1 else ()
    # over a group holding every goal's network: every impact member on the rows of every
    # partner given as a distribution, so that they share one input and one forward call
    # whichever goals each partner keeps (an announced partner's goal also on that partner's
    # row); the compiled forward's rows are independent: the same bits as from any group
    distributions = [k for k, partner in enumerate(partners) if partner.probs is not None]
    if distributions and len(members) - 1 == len(checked.runtime.domain.goals):
        served[1:] = [list(distributions) for _ in members[1:]]
        for position, partner in enumerate(partners):
            if partner.probs is None:
                bisect.insort(served[member_of[partner.goals[0]]], position)
        for position, partner in enumerate(partners):
            for goal in partner.goals:
                j = member_of[goal]
                slots[(position, goal)] = (j, served[j].index(position))
    else:  # each member on the rows of the partners that need it, in order
        for position, partner in enumerate(partners):
            for goal in partner.goals:
                j = member_of[goal]
                slots[(position, goal)] = (j, len(served[j]))
                served[j].append(position)
    first_unit = np.cumsum([0] + [len(rows) for rows in served[1:]])  # per member j-1
    by_count: dict[int, list[int]] = {}
    for position, partner in enumerate(partners):
        if partner.probs is not None:
            by_count.setdefault(len(partner.goals), []).append(position)
    mixes = tuple(
        (
            tuple(positions),
            np.array(
                [
                    [
                        first_unit[slots[(k, goal)][0] - 1] + slots[(k, goal)][1]
                        for goal in checked.partners[k].goals
                    ]
                    for k in positions
                ],
                dtype=np.intp,
            ),
        )
        for positions in by_count.values()
    )
    runs = tuple((tuple(rows), len(list(same))) for rows, same in itertools.groupby(served[1:]))
    return Layout(runs, slots, models_used(checked, members, group), mixes)


def models_used(
    checked: CheckedRequest, members: Sequence[Member], group: StackedGroup
) -> tuple[ModelUsed, ...]:
    """The task (or joint) network, then per partner (in request order) each goal's impact net."""
    first = group.nets[0]
    used = [ModelUsed(members[0][0], first.name, first.version, first.sha256, None, members[0][1])]
    if len(members) > 1:
        net_of = {goal: group.nets[j] for j, (role, goal) in enumerate(members) if role == "impact"}
        for partner in checked.partners:
            for goal in partner.goals:
                net = net_of[goal]
                used.append(
                    ModelUsed("impact", net.name, net.version, net.sha256, partner.index, goal)
                )
    return tuple(used)


def member_inputs(
    checked: CheckedRequest, members: Sequence[Member], group: StackedGroup, layout: Layout
) -> list[np.ndarray]:
    """Each member's input rows (module docstring, table)."""
    obs_BD, n_agents, domain = checked.obs_BD, checked.n_agents, checked.runtime.domain
    if members[0][0] == "joint":
        joint = group.nets[0]
        if joint.spec.obs_dim != obs_BD.shape[1]:
            raise InvalidRequest(
                "observations",
                f"the joint network {joint.name} takes {joint.spec.obs_dim} features, "
                f"the observations have {obs_BD.shape[1]} (a joint network knows no bystanders)",
            )
        return [obs_BD]
    views_BKP = domain.task_views(obs_BD, n_agents)
    inputs = [views_BKP.reshape(-1, views_BKP.shape[-1])]
    if len(members) == 1:
        return inputs
    # partner p's impact view is the task view of agent p (`envs.base`)
    partners = checked.partners
    joined: dict[tuple[int, ...], np.ndarray] = {}  # members serving the same partners share
    for positions, count in layout.position_runs:
        rows = joined.get(positions)
        if rows is None:
            if len(positions) == 1:
                rows = views_BKP[:, partners[positions[0]].index - 1]
            else:  # partner after partner, B rows each
                columns = [partners[position].index - 1 for position in positions]
                rows_PBF = views_BKP[:, columns].transpose(1, 0, 2)
                rows = rows_PBF.reshape(-1, views_BKP.shape[-1])
            joined[positions] = rows
        inputs += [rows] * count
    return inputs


def impact_q(checked: CheckedRequest, q_members: MemberQ, layout: Layout) -> np.ndarray:
    """One impact Q-vector per partner, (B, P, A) float64; a goal distribution is mixed by its
    probabilities (§3.2: the expected impact Q, `policy.blend.mix_goal_beliefs`' einsum without
    its checks: a non-finite Q goes on to the caller's overflow check). Distributions over
    equally many goals (a session's whole beliefs) share one mix (`compiled_mix_goals`, else
    numpy's einsum), on the impact members' rows as the forward left them
    (`MemberQ.rows_from`): a numpy call costs more than its arithmetic at a few rows."""
    batch, n_actions = checked.obs_BD.shape[0], checked.runtime.domain.n_actions
    partners = checked.partners
    if not partners:
        return np.zeros((batch, 0, n_actions))
    per_partner: list[np.ndarray | None] = [None] * len(partners)
    for position, partner in enumerate(partners):
        if partner.probs is None:
            j, block = layout.slots[(position, partner.goals[0])]
            per_partner[position] = q_members[j][block * batch : (block + 1) * batch]
    if layout.mixes:
        q_all = q_members.rows_from(1)  # the impact members' rows, one after the other
        for positions, units_PG in layout.mixes:
            probs = [partners[k].probs or () for k in positions]  # all distributions here
            q_BPA = compiled_mix_goals(q_all, units_PG, probs, batch)
            if q_BPA is None:  # the numpy reference
                rows_PGB = units_PG[:, :, None] * batch + np.arange(batch)
                q_PGBA = q_all[rows_PGB].astype(np.float64)
                q_BPA = np.einsum("pg,pgba->bpa", np.array(probs, np.float64), q_PGBA)
            if len(positions) == len(partners):  # every partner mixed (a session's beliefs)
                return np.ascontiguousarray(q_BPA)
            for i, position in enumerate(positions):
                per_partner[position] = q_BPA[:, i]
    # np.stack(per_partner, axis=1)'s values from one np.array (np.stack's Python steps cost
    # more than the arithmetic at a few rows); a copy only where B > 1 makes the transpose strided
    q_PBA = np.array(per_partner, dtype=np.float64)
    return np.ascontiguousarray(q_PBA.transpose(1, 0, 2))
