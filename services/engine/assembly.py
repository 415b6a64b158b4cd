"""Pure steps of `act` between the cache and the blend: build each network's input rows from the
views, regroup the Q-values per partner, list the models used, sample the actions.

Row layout of the member inputs (B observation rows, K task views, U_g partners with goal g):

| member          | input rows                                   | Q-values used as                   |
|-----------------|----------------------------------------------|------------------------------------|
| task            | (B*K, pair_dim), row b*K + k = view k of b   | mean over k -> q_task (B, A)       |
| impact, goal g  | (U_g*B, pair_dim), block u = the impact view | block u -> partner u's Q for g     |
|                 | of the u-th partner with goal g              |                                    |
| joint           | (B, obs_dim), the whole observation          | q (B, A)                           |

`slots[(position, goal)] = (member, block)` says where a partner's Q for a goal lies.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from policy.regret_bound import DEFAULT_EPSILON_PER_ALPHA
from services.engine.errors import InvalidRequest
from services.engine.messages import DEFAULT_TEMPERATURE, ActRequest, Member, ModelUsed
from services.engine.networks import StackedGroup
from services.engine.validation import CheckedRequest

Slots = dict[tuple[int, str], tuple[int, int]]
MEMO_MAX = 256  # request layouts remembered per stacked group (cleared when full)


class Layout(NamedTuple):
    """What a request layout (members, partners' indices and goals) fixes, per stacked group."""

    positions: tuple[tuple[int, ...], ...]  # per impact member: the partners it serves, in order
    slots: Slots  # (partner position, goal) -> (member, block)
    models: tuple[ModelUsed, ...]  # `models_used`, the same objects on every call
    # the goal distributions' mixes (`impact_q`): per goal count, the partners' positions and
    # (P', G) rows of their goals' Q-values among the impact members' rows at batch 1 (member j
    # has one row per partner it serves; at batch B each row is B rows)
    mixes: tuple[tuple[tuple[int, ...], np.ndarray], ...]


def _layout(checked: CheckedRequest, members: Sequence[Member], group: StackedGroup) -> Layout:
    """The layout of this request's partners over the group's members, remembered on the
    group (`StackedGroup.memo`): with a belief over 35 goals and 4 partners that is 140 slots
    and 141 models, ~0.3 ms of Python to work out again on every session step."""
    key = ("assembly", tuple(members), tuple((p.index, p.goals) for p in checked.partners))
    layout: Layout | None = group.memo.get(key)
    if layout is not None:
        return layout
    member_of = {goal: j for j, (role, goal) in enumerate(members) if role == "impact"}
    served: list[list[int]] = [[] for _ in members]
    slots: Slots = {}
    for position, partner in enumerate(checked.partners):
        for goal in partner.goals:
            j = member_of[goal]
            slots[(position, goal)] = (j, len(served[j]))
            served[j].append(position)
    first_unit = np.cumsum([0] + [len(partners) for partners in served[1:]])  # per member j-1
    by_count: dict[int, list[int]] = {}
    for position, partner in enumerate(checked.partners):
        if partner.probs is not None:
            by_count.setdefault(len(partner.goals), []).append(position)
    mixes = tuple(
        (tuple(positions), np.array([
            [first_unit[slots[(k, goal)][0] - 1] + slots[(k, goal)][1]
             for goal in checked.partners[k].goals]
            for k in positions
        ], dtype=np.intp))
        for positions in by_count.values()
    )  # fmt: skip
    layout = Layout(
        tuple(map(tuple, served[1:])), slots, tuple(_models_used(checked, members, group)), mixes
    )
    if len(group.memo) >= MEMO_MAX:
        group.memo.clear()
    group.memo[key] = layout
    return layout


def member_inputs(
    checked: CheckedRequest, members: Sequence[Member], group: StackedGroup
) -> tuple[list[np.ndarray], Layout | None]:
    """Each member's input rows (table above) and the request's layout (None: no impact
    network)."""
    obs_BD, n_agents, domain = checked.obs_BD, checked.n_agents, checked.runtime.domain
    if members[0][0] == "joint":
        joint = group.nets[0]
        if joint.spec.obs_dim != obs_BD.shape[1]:
            raise InvalidRequest(
                "observations",
                f"the joint network {joint.name} takes {joint.spec.obs_dim} features, "
                f"the observations have {obs_BD.shape[1]} (a joint network knows no bystanders)",
            )
        return [obs_BD], None
    views_BKP = domain.task_views(obs_BD, n_agents)
    inputs = [views_BKP.reshape(-1, views_BKP.shape[-1])]
    if len(members) == 1:
        return inputs, None
    layout = _layout(checked, members, group)
    views = [domain.impact_view(obs_BD, n_agents, p.index) for p in checked.partners]
    joined: dict[tuple[int, ...], np.ndarray] = {}  # members serving the same partners share
    for positions in layout.positions:
        if positions not in joined:
            blocks = [views[position] for position in positions]
            joined[positions] = blocks[0] if len(blocks) == 1 else np.concatenate(blocks)
        inputs.append(joined[positions])
    return inputs, layout


def impact_q(
    checked: CheckedRequest, q_members: Sequence[np.ndarray], layout: Layout | None
) -> np.ndarray:
    """One impact Q-vector per partner, (B, P, A); a goal distribution is mixed by its
    probabilities (§3.2: the expected impact Q, `mix_goal_beliefs`' einsum on the same float64
    values, without its checks: a non-finite Q goes on to the caller's overflow check).
    Distributions over equally many goals (a session's whole beliefs) share one einsum: its
    (b, p, a) sums are those of one einsum per partner, bit for bit (checked on random data)."""
    batch, n_actions = checked.obs_BD.shape[0], checked.runtime.domain.n_actions
    partners = checked.partners
    if layout is None or not partners:
        return np.zeros((batch, 0, n_actions))
    per_partner: list[np.ndarray | None] = [None] * len(partners)
    for position, partner in enumerate(partners):
        if partner.probs is None:
            j, block = layout.slots[(position, partner.goals[0])]
            per_partner[position] = q_members[j][block * batch : (block + 1) * batch]
    if layout.mixes:
        q_all = np.concatenate(q_members[1:])  # the impact members' rows, one after the other
        for positions, units_PG in layout.mixes:
            # (B, P', G, A) float64 in C order, the operand mix_goal_beliefs passes
            if batch == 1:
                q_BPGA = q_all[units_PG][None].astype(np.float64)
            else:
                rows_PGB = units_PG[:, :, None] * batch + np.arange(batch)
                q_BPGA = q_all[rows_PGB].transpose(2, 0, 1, 3).astype(np.float64, order="C")
            probs_PG = np.array([partners[k].probs for k in positions], np.float64)
            probs_BPG = (
                probs_PG[None]
                if batch == 1
                else np.ascontiguousarray(np.broadcast_to(probs_PG, q_BPGA.shape[:3]))
            )
            q_BPA = np.einsum("bpg,bpga->bpa", probs_BPG, q_BPGA)
            for i, position in enumerate(positions):
                per_partner[position] = q_BPA[:, i]
    return np.stack(per_partner, axis=1)  # type: ignore[arg-type]  # every slot filled


def models_used(
    checked: CheckedRequest, members: Sequence[Member], group: StackedGroup
) -> list[ModelUsed]:
    """The task (or joint) network, then per partner (in request order) each goal's impact net
    (the same `ModelUsed` objects for every request of one layout)."""
    if len(members) == 1:
        return _models_used(checked, members, group)
    return list(_layout(checked, members, group).models)


def _models_used(
    checked: CheckedRequest, members: Sequence[Member], group: StackedGroup
) -> list[ModelUsed]:
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
    return used


def sample_actions(probs_BA: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """One action per row drawn from `probs_BA` by inverse CDF (one uniform per row, in order):
    the first action whose cumulative probability exceeds u, so a p = 0 action is never drawn."""
    cdf_BA = np.cumsum(probs_BA, axis=1)
    u_B1 = rng.random((probs_BA.shape[0], 1)) * cdf_BA[:, -1:]
    return np.minimum((cdf_BA <= u_B1).sum(axis=1), probs_BA.shape[1] - 1)


def regret_bound_of(
    request: ActRequest, group: StackedGroup, checked: CheckedRequest
) -> np.ndarray | None:
    """ε of `aail_bounded` per row, (B,) (`policy.regret_bound`): the request's, else
    `DEFAULT_EPSILON_PER_ALPHA` × the task network's training α; 0 on the rows where the
    environment tells that the ego's own goal is not reached yet (the progress guard, R2).
    None for the other methods."""
    if request.method != "aail_bounded":
        return None
    if request.regret_bound is not None:
        epsilon = float(request.regret_bound)
    else:
        epsilon = DEFAULT_EPSILON_PER_ALPHA * float(group.nets[0].alpha or DEFAULT_TEMPERATURE)
    runtime = checked.runtime
    reached = runtime.domain.goal_reached(checked.obs_BD, checked.n_agents, request.ego_goal)
    if reached is None:
        return np.full(checked.obs_BD.shape[0], epsilon)
    return np.where(reached, epsilon, 0.0)


def finished_rows(request: ActRequest, checked: CheckedRequest) -> np.ndarray | None:
    """Rows, (B,) bool, where `aail_bounded` blends with a flat task Q (R3 of
    `policy.regret_bound`): the environment tells that the ego's goal is reached for good
    (`Domain.goal_is_final`: a served dish). None where no row is (and for the other methods)."""
    domain = checked.runtime.domain
    if request.method != "aail_bounded" or not domain.goal_is_final:
        return None
    reached = domain.goal_reached(checked.obs_BD, checked.n_agents, request.ego_goal)
    if reached is None or not reached.any():
        return None
    return np.asarray(reached, dtype=bool)


def goal_kept_of(
    request: ActRequest, checked: CheckedRequest, epsilon_B: np.ndarray | None
) -> np.ndarray | None:
    """(B, A) bool for R4 of `policy.regret_bound`: the actions that keep the ego's reached goal,
    on the rows where `aail_bounded` blends (ε > 0); every action elsewhere. None where nothing
    is to keep (another method, no row blending, or a goal that cannot be lost)."""
    if epsilon_B is None or not (epsilon_B > 0.0).any():
        return None
    domain = checked.runtime.domain
    kept_BA = domain.goal_kept(checked.obs_BD, checked.n_agents, request.ego_goal)
    if kept_BA is None:
        return None
    return np.where((epsilon_B > 0.0)[:, None], kept_BA, True)
