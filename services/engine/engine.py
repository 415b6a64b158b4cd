"""`InferenceEngine`: the blended action distributions of paper §3.3 for B observation rows.
One engine per server process, shared by the REST and gRPC transports. An act reads top to
bottom in `_act`; every batch size takes the same steps (a single observation is B = 1).

| step     | what                                                          | where          |
|----------|---------------------------------------------------------------|----------------|
| check    | every field; bad ones -> `InvalidRequest(field, message)`     | `validation`   |
| resolve  | `{env}/task/{ego_goal}` and `{env}/impact/{g}` for every      | `_plan_members`|
|          | partner goal g with probability > 0 (sl: the task net only;   | `model_cache`  |
|          | jl: `{env}/joint/{ego}+{p1}+...`, partners ordered by index), |                |
|          | by `name@alias` or a pinned version                           |                |
| stack    | the networks' weights, once per combination of versions       | `model_cache`  |
| inputs   | each member's input rows from the domain's views (table below)| `_inputs`      |
| forward  | `networks.forward_group`: every member on its rows            | `networks`     |
| reduce   | task Q = mean over the K task views; one impact Q per partner,| `mean_views`,  |
|          | a goal distribution's the expectation over its goals (§3.2)   |                |
| blend    | `policy.blend.blend_checked` (eqs. 8-10; R1 for aail_bounded);| `policy.blend` |
|          | jl: the joint Q alone; aail_budget: AAIL's policy mixed with  | `spend_budget` |
|          | the task's within the episode's budget (eqs. B1-B4)           |                |
| sample   | inverse CDF per row from `default_rng(seed)`, one stream over | `sample_rows`  |
|          | the rows (row r of a batch is not row 1 of a single request)  |                |

Member input rows (B observation rows, K task views, U_g partners with goal g):

| member          | input rows                                   | Q-values used as                   |
|-----------------|----------------------------------------------|------------------------------------|
| task            | (B*K, pair_dim), row b*K + k = view k of b   | mean over k -> q_task (B, A)       |
| impact, goal g  | (U_g*B, pair_dim), block u = the impact view | block u -> partner u's Q for g     |
|                 | of the u-th partner with goal g              |                                    |
| joint           | (B, obs_dim), the whole observation          | q (B, A)                           |

What a request's shape fixes (its networks, `_plan_members`; where each partner's Q-values lie
and the models used, `_layout`) is computed once and remembered: the plans by request shape,
the layouts on the stacked group they index (`StackedGroup.memo`).

Goal distributions. A request with a partner given as a goal distribution (a session's
beliefs, or /v1/act's `goal_probs`) takes its networks from its own stacked group when that is
stacked; otherwise from the group of the task network and EVERY goal's impact network (stacked
once per alias), except that a small own group (at most a quarter of the goals) is stacked when
its request shape comes a second time. Over a group holding every goal's network, each impact
network runs on the rows of every partner given as a distribution (an announced partner's
network on its row too): one input and one forward call, whatever goals each partner keeps. A
top-goal session (`blend_max_goals`) asks for a new set of goals at almost every step, and
stacking a group costs more than evaluating every goal (docs/performance.md); a fixed small
distribution gets its own group from its second request on. Either way the answer is the same,
bit for bit: the compiled forward's rows are independent, so a network's Q-values do not depend
on the group or the other rows, and a partner's mix adds its goals in its own order. Hence the
rule holds for the compiled forward only, without pinned versions, and where every goal's
network can be resolved and loaded (after a failure, every goal's group is asked for again only
once the store changed).

Choices the paper leaves open: the temperature is the request's, else the task (jl: joint)
model's training α (`lineage.config["alpha"]`), else 0.02. Whether AAIL standardises the
Q-vectors before eq. 8 is the environment's `Domain.blend_normalisation` (`policy.blend`). For
jl the "task" diagnostics describe the joint policy (`task_weight` 1, partner weights 0); jl
needs each partner's announced goal. Partners given with `sl` are checked but load no network.
Goal inference for sessions (partners' actions under every goal's task network) is
`goal_inference`.

Hot reload: `refresh()` (or the daemon thread of `start_refresh_thread`, every
`refresh_interval_s`) swaps moved aliases to their new versions, loaded before the swap; see
`model_cache`.
"""

from __future__ import annotations

import bisect
import itertools
import logging
import threading
from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import NamedTuple

import numpy as np

from envs.registry import known_envs
from model_store.errors import InvalidArgument, ModelStoreError
from model_store.naming import joint_model_name
from model_store.store import ModelStore
from policy.belief_compiled import compiled_mix_goals
from policy.blend import BlendMethod, blend_checked
from policy.maths import boltzmann
from policy.regret_bound import DEFAULT_EPSILON_PER_ALPHA, keep_goal_rows
from policy.regret_budget import (
    BUDGET_EPSILON_PER_ALPHA,
    DEFAULT_BUDGET_FRACTION,
    budget_rows,
    initial_budget,
)
from policy.row_forward import mean_views
from policy.sampling import sample_rows
from services.engine import networks
from services.engine.environments import env_runtime
from services.engine.errors import EngineError, InvalidRequest, ModelNotFound, ModelUnavailable
from services.engine.goal_inference import goal_log_likelihoods, recover_partner_actions
from services.engine.messages import (
    DEFAULT_TEMPERATURE,
    ActColumns,
    ActRequest,
    ActResult,
    EngineStats,
    EngineStatus,
    EnvInfo,
    Member,
    ModelUsed,
)
from services.engine.model_cache import ModelCache
from services.engine.networks import MemberQ, StackedGroup, forward_group, overflow_error
from services.engine.validation import CheckedPartner, CheckedRequest, check_request

log = logging.getLogger(__name__)

MEMBER_PLANS_MAX = 1024  # request shapes remembered (the table is cleared when full)
CONSTANTS_MAX = 256  # constant arrays remembered (`_constant`; cleared when full)
LAYOUTS_MAX = 256  # request layouts remembered per stacked group (cleared when full)


class InferenceEngine:
    """Resolve, load, stack, evaluate, blend and sample (module docstring)."""

    def __init__(
        self,
        store: ModelStore,
        *,
        cache_size: int = 256,
        stack_cache_size: int = 64,
        refresh_interval_s: float = 2.0,
        max_batch: int = 4096,
    ) -> None:
        for name, value in (("cache_size", cache_size), ("stack_cache_size", stack_cache_size)):
            if value < 1:
                raise ValueError(f"{name}: expected >= 1, got {value}")
        if not refresh_interval_s > 0:
            raise ValueError(f"refresh_interval_s: expected > 0, got {refresh_interval_s}")
        if max_batch < 1:
            raise ValueError(f"max_batch: expected >= 1, got {max_batch}")
        self.store = store
        self.refresh_interval_s = refresh_interval_s
        self.max_batch = max_batch
        self.stats = EngineStats()
        self.cache = ModelCache(
            store, self.stats, cache_size=cache_size, stack_cache_size=stack_cache_size
        )
        self._rng = np.random.default_rng()  # for unseeded requests
        # request shape -> the networks it needs (`_plan_members`; pure, so never stale)
        self._member_plans: dict[tuple[object, ...], MemberPlan] = {}
        # a distributions-only plan (by the id of its needs) -> "seen", or "stacked" once its
        # own group was stacked (`_distributions_group`)
        self._shapes_seen: dict[int, str] = {}
        # (env, method, ego goal, alias) -> every goal's plan, and the store generation
        # (`stats.refreshes`) at which one of its networks was missing (None: none was)
        self._catalogue_plans: dict[tuple[str, ...], CataloguePlan] = {}
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    # --- act -------------------------------------------------------------------------------
    def act(self, request: ActRequest) -> list[ActResult]:
        """One result per observation row; `EngineError` on bad input or missing models."""
        return self._counted(request, None).rows()

    def act_columns(self, request: ActRequest) -> ActColumns:
        """`act`'s results as columns (one array per field, the models once): the same values,
        sampled actions, errors and stats; `act_columns(r).rows()` equals `act(r)`."""
        return self._counted(request, None)

    def act_checked(self, request: ActRequest, checked: CheckedRequest | None) -> list[ActResult]:
        """`act`, given what `check_request(request)` would return (None: check it here).
        Internal, for a caller that checked the request's parts itself and builds `checked`
        from them (a session: settings once, the observation and its belief's distribution on
        each step); `request.observations` and `request.partners` are then not read."""
        return self._counted(request, checked).rows()

    def _counted(self, request: ActRequest, checked: CheckedRequest | None) -> ActColumns:
        try:
            answer = self._act(request, checked)
        except EngineError:
            self.stats.errors += 1
            raise
        self.stats.requests += 1
        self.stats.rows += len(answer)
        return answer

    def _act(self, request: ActRequest, checked: CheckedRequest | None) -> ActColumns:
        """Check, resolve, forward, blend, sample (module docstring)."""
        public = checked is None  # a transport's request, not a session's (which checks its own)
        if checked is None:
            checked = check_request(request, self.max_batch)
        domain, method = checked.runtime.domain, request.method
        members, group = self._resolve_members(request, checked, check_pins=public)
        layout = _layout(checked, members, group)
        q_members = forward_group(group, _inputs(checked, members, group, layout))
        batch, n_actions = checked.obs_BD.shape[0], domain.n_actions
        if method == "jl":
            q_task_BA = q_members[0].astype(np.float64)
        else:  # the task Q averaged over the K task views (one per other agent)
            q_task_BA = mean_views(q_members[0], q_members[0].shape[0] // batch)
        epsilon_B, finished_B = aail_bounded_guard(request, group, checked)
        if finished_B is not None:  # R3: nothing left to earn, the exact task Q is flat
            flat_BA = np.broadcast_to(q_task_BA.mean(axis=1, keepdims=True), q_task_BA.shape)
            q_task_BA = np.where(finished_B[:, None], flat_BA, q_task_BA)
        if method in ("nail", "aail", "aail_bounded", "aail_budget"):
            # aail_budget: AAIL bounded by R1 at every step, then the budget (B1-B4)
            blend_method: BlendMethod = "aail_bounded" if method == "aail_budget" else method
            q_impact_BPA = _impact_q(checked, q_members, layout)
        else:  # sl, jl: the task/joint network alone
            blend_method = "sl"
            q_impact_BPA = np.zeros((batch, 0, n_actions))
        temperature = request.temperature or group.nets[0].alpha or DEFAULT_TEMPERATURE
        if method == "aail_budget":  # R1's ε at every step: no oracle sets it to 0
            epsilon_B = np.full(batch, budget_epsilon(request, group))
        # every partner slot is used, one temperature for all rows
        try:
            blended = blend_checked(
                blend_method,
                q_task_BA,
                q_impact_BPA,
                _constant(q_impact_BPA.shape[:2], True),
                _constant((batch,), float(temperature)),
                domain.blend_normalisation == "standardise",
                epsilon_B,
            )
        except FloatingPointError:  # float32 outputs overflowed: on huge observations, or ...
            raise overflow_error(group, checked.obs_BD, "observations") from None
        partner_weights_BP = blended.partner_weights_BP
        if blend_method == "sl":  # no impact network was evaluated: every partner weighs 0
            partner_weights_BP = np.zeros((batch, len(checked.partners)))
        rng = self._rng if request.seed is None else np.random.default_rng(request.seed)
        probs_BA = blended.probs_BA
        kept_BA = goal_kept_of(request, checked, epsilon_B)
        if kept_BA is not None:  # R4: no action that loses the reached goal where one keeps it
            probs_BA = keep_goal_rows(probs_BA, kept_BA)
        spent_B = total_B = None
        if method == "aail_budget":
            probs_BA, spent_B, total_B = spend_budget(
                request, checked, q_task_BA, q_impact_BPA, probs_BA, float(temperature)
            )
        # one uniform per row, in order: row r of a batch is not row 1 of a single request
        actions_B, greedy_B = sample_rows(probs_BA, rng.random((batch,)))
        return ActColumns(
            method=method,
            models=list(layout.models),
            probs=probs_BA,
            actions=actions_B,
            greedy_actions=greedy_B,
            task_entropies=blended.task_entropy_B,
            task_weights=blended.task_weight_B,
            partner_weights=partner_weights_BP,
            budget_spent=spent_B,
            budget_total=total_B,
        )

    def _resolve_members(
        self, request: ActRequest, checked: CheckedRequest, *, check_pins: bool = False
    ) -> tuple[tuple[Member, ...], StackedGroup]:
        """The networks the request needs (`_plan_members`) and their stacked group, resolved in
        order (so the first missing one is the one reported). A cached plan is the same tuple
        each time, so the cache resolves it as one fixed set (`ModelCache.resolve_group`).
        `check_pins`: a pinned version of a model the request does not use is an error (a pin
        that silently does nothing hides a typo)."""
        key = (
            checked.runtime.domain.name,
            request.method,
            request.ego_goal,
            checked.partners_key,
        )
        plan = self._member_plans.get(key)
        if plan is None:
            plan = _plan_members(request, checked)
            if len(self._member_plans) >= MEMBER_PLANS_MAX:
                self._member_plans.clear()
                self._shapes_seen.clear()  # keyed by the plans' ids
            self._member_plans[key] = plan
        members, needs = plan
        if check_pins and request.versions:
            _check_pins_used(request.versions, needs)
        if _with_distributions(request, checked):
            served = self._distributions_group(request, checked, members, needs)
            if served is not None:
                return served
        _, group = self.cache.resolve_group(
            needs, request.alias, request.versions, members, checked.runtime.domain
        )
        return members, group

    def _distributions_group(
        self,
        request: ActRequest,
        checked: CheckedRequest,
        members: tuple[Member, ...],
        needs: tuple[tuple[str, str, str], ...],
    ) -> tuple[tuple[Member, ...], StackedGroup] | None:
        """Where a request with a partner given as a goal distribution is served from (module
        docstring, "Goal distributions"): its own group when that is stacked; else every
        goal's group, unless its own is small and asked for before without being stacked
        (then None: stack it). None also where every goal's group cannot serve."""
        group = self.cache.cached_group(needs, request.alias, members)
        if group is not None:
            return members, group
        seen = self._shapes_seen.get(id(needs))  # None, "seen" or "stacked"
        small = len(members) - 1 <= len(checked.runtime.domain.goals) // 4
        if seen == "seen" and small:  # asked for again: its own forward is worth a stack
            self._shapes_seen[id(needs)] = "stacked"
            return None
        self._shapes_seen.setdefault(id(needs), "seen")
        return self._catalogue_group(request, checked, len(members))

    def _catalogue_group(
        self, request: ActRequest, checked: CheckedRequest, own_members: int
    ) -> tuple[tuple[Member, ...], StackedGroup] | None:
        """The stacked group of the task network and EVERY goal's impact network, or None:
        the request's own networks are those already, or one of every goal's is missing or
        cannot be loaded (then not tried again until the store changes)."""
        domain = checked.runtime.domain
        key = (domain.name, request.method, request.ego_goal, request.alias)
        plan = self._catalogue_plans.get(key)
        if plan is None or (plan[2] is not None and plan[2] != self.stats.refreshes):
            goals = tuple(domain.goals)
            every = CheckedPartner(0, goals, tuple(1.0 for _ in goals))
            members, needs = _plan_members(request, replace(checked, partners=(every,)))
            plan = (members, needs, None)
            if len(self._catalogue_plans) >= MEMBER_PLANS_MAX:
                self._catalogue_plans.clear()
            self._catalogue_plans[key] = plan
        members, needs, failed_at = plan
        if failed_at is not None or own_members == len(members):  # missing, or the same group
            return None
        try:
            _, group = self.cache.resolve_group(needs, request.alias, {}, members, domain)
        except (ModelNotFound, ModelUnavailable):  # the request's own networks may serve:
            # not tried again before the store changes (a failing load per request would cost
            # more than the groups it saves; the request's own path reports its own errors)
            self._catalogue_plans[key] = (members, needs, self.stats.refreshes)
            return None
        self.stats.catalogue_group_acts += 1
        return members, group

    # --- goal inference (`goal_inference`) --------------------------------------------------
    def goal_log_likelihoods(
        self,
        env: str,
        observation: np.ndarray,
        partners: Sequence[int],
        actions: Sequence[int],
        *,
        alias: str = "production",
        versions: Mapping[str, int] | None = None,
        temperature: float | None = None,
    ) -> np.ndarray:
        """(P, G) log π_g(actions[p] | partner p's view of the ego's `observation`), goals in
        the env's catalogue order: every task network in one stacked pass."""
        return goal_log_likelihoods(
            self.cache,
            env,
            observation,
            partners,
            actions,
            alias=alias,
            versions=versions,
            temperature=temperature,
        )

    def recover_partner_actions(
        self, env: str, previous: np.ndarray, current: np.ndarray, partners: Sequence[int]
    ) -> list[int]:
        """Each partner's most likely action between two consecutive ego observations."""
        return recover_partner_actions(env, previous, current, partners)

    # --- environments, hot reload, status --------------------------------------------------
    def envs(self) -> list[EnvInfo]:
        """Every registered environment: goals, action meanings, observation layouts, methods."""
        return [env_runtime(name).info for name in known_envs()]

    def refresh(self) -> bool:
        """Poll the store's change token and swap moved aliases to their new versions (loaded
        first). True when a served alias moved; store errors are logged and give False."""
        return self.cache.refresh()

    def start_refresh_thread(self) -> None:
        """Call `refresh()` every `refresh_interval_s` in a daemon thread (idempotent)."""
        if self._thread is not None and self._thread.is_alive():
            return
        self._stop.clear()
        self._thread = threading.Thread(
            target=self._refresh_loop, name="coexist-engine-refresh", daemon=True
        )
        self._thread.start()

    def _refresh_loop(self) -> None:
        while not self._stop.wait(self.refresh_interval_s):
            try:
                self.refresh()
            except Exception:  # never let the thread die: the server would stop reloading
                log.exception("hot reload: unexpected error, will retry")

    def stop(self) -> None:
        """Stop the refresh thread (the engine still answers requests)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=max(5.0, 2 * self.refresh_interval_s))
            self._thread = None

    def status(self) -> EngineStatus:
        """Readiness: whether the store answers, what is loaded and which versions are served."""
        error: str | None = None
        try:
            self.store.change_token()
        except ModelStoreError as exc:
            error = str(exc)
        return EngineStatus(
            store_reachable=error is None,
            store_error=error,
            models_loaded=self.cache.models_loaded(),
            versions_served=self.cache.versions_served(),
            change_token=self.cache.last_token,
            refresh_thread_alive=self._thread is not None and self._thread.is_alive(),
        )

    def __enter__(self) -> InferenceEngine:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.stop()


MemberPlan = tuple[tuple[Member, ...], tuple[tuple[str, str, str], ...]]
# every goal's plan, and the store generation at which one of its networks was missing
CataloguePlan = tuple[tuple[Member, ...], tuple[tuple[str, str, str], ...], int | None]
Slots = dict[tuple[int, str], tuple[int, int]]


def _check_pins_used(pinned: Mapping[str, int], needs: Sequence[tuple[str, str, str]]) -> None:
    used = [name for name, _, _ in needs]
    for name in pinned:
        if name not in used:
            raise InvalidRequest(
                f"versions[{name}]",
                f"this request uses no model {name!r} (it uses {', '.join(used)}): a pin must "
                "name one of them",
            )


def _with_distributions(request: ActRequest, checked: CheckedRequest) -> bool:
    """Whether every goal's group may serve the request (module docstring, "Goal
    distributions"): a blend of impact networks, a partner given as a goal distribution, no
    pinned version, and the compiled forward (whose rows are independent: the same Q-values,
    bit for bit, from any group holding the networks)."""
    for partner in checked.partners:  # a loop, not any(): most requests announce every goal
        if partner.probs is not None:
            break
    else:
        return False
    return (
        request.method in ("nail", "aail", "aail_bounded", "aail_budget")
        and not request.versions
        and networks.ROW_FORWARD  # read at call time: tests switch it
    )


def _plan_members(request: ActRequest, checked: CheckedRequest) -> MemberPlan:
    """The networks a request needs, as members and (model name, field to blame, why needed):
    the task (or joint) network first, then the impact networks sorted by name (so that the
    order in which partners are listed does not change the stacked group)."""
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
        return (("joint", request.ego_goal),), ((name, "method", why),)
    members: list[Member] = [("task", request.ego_goal)]
    needs = [(runtime.task_names[request.ego_goal], "ego_goal", "no task network")]
    if request.method == "sl":
        return tuple(members), tuple(needs)
    field_of: dict[str, str] = {}  # goal -> the first partner field that asks for it
    for i, partner in enumerate(checked.partners):
        suffix = "goal" if partner.probs is None else "goal_probs"
        for goal in partner.goals:
            field_of.setdefault(goal, f"partners[{i}].{suffix}")
    for goal in sorted(field_of, key=runtime.impact_names.__getitem__):
        needs.append((runtime.impact_names[goal], field_of[goal], "no impact network"))
        members.append(("impact", goal))
    return tuple(members), tuple(needs)


class Layout(NamedTuple):
    """What a request layout (members, partners' indices and goals) fixes, per stacked group."""

    # the impact members in order, as runs of consecutive members serving the same partners:
    # (the partners' positions, in order; how many members); one run for a belief's group,
    # whose members all take the same input rows
    position_runs: tuple[tuple[tuple[int, ...], int], ...]
    slots: Slots  # (partner position, goal) -> (member, block)
    models: tuple[ModelUsed, ...]  # the models used, the same objects on every call
    # the goal distributions' mixes (`_impact_q`): per goal count, the partners' positions and
    # (P', G) rows of their goals' Q-values among the impact members' rows at batch 1 (member j
    # has one row per partner it serves; at batch B each row is B rows)
    mixes: tuple[tuple[tuple[int, ...], np.ndarray], ...]


def _layout(checked: CheckedRequest, members: Sequence[Member], group: StackedGroup) -> Layout:
    """The layout of this request's partners over the group's members, remembered on the
    group (with a belief over 35 goals and 4 partners: 140 slots and 141 models)."""
    # an announced goal is not a distribution over it (`partners_key` tells them apart)
    key = ("layout", tuple(members), checked.partners_key)
    layout: Layout | None = group.memo.get(key)
    if layout is not None:
        return layout
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
    layout = Layout(runs, slots, _models_used(checked, members, group), mixes)
    if len(group.memo) >= LAYOUTS_MAX:
        group.memo.clear()
    group.memo[key] = layout
    return layout


def _models_used(
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


def _inputs(
    checked: CheckedRequest, members: Sequence[Member], group: StackedGroup, layout: Layout
) -> list[np.ndarray]:
    """Each member's input rows (module docstring, second table)."""
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
    # partner p's impact view is the task view of agent p (`Domain.impact_view`)
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


def _impact_q(checked: CheckedRequest, q_members: MemberQ, layout: Layout) -> np.ndarray:
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


_CONSTANTS: dict[tuple[tuple[int, ...], bool | float, type], np.ndarray] = {}


def _constant(shape: tuple[int, ...], value: bool | float) -> np.ndarray:
    """A read-only array of `shape` filled with `value` (bool or float64), made once per shape
    and value: the blend's mask and temperatures are the same for every request of a shape,
    and building them took four numpy calls per act."""
    key = (shape, value, type(value))  # the type too: True == 1.0 as keys
    array = _CONSTANTS.get(key)
    if array is None:
        array = np.full(shape, value, dtype=bool if type(value) is bool else np.float64)
        array.flags.writeable = False
        if len(_CONSTANTS) >= CONSTANTS_MAX:
            _CONSTANTS.clear()
        _CONSTANTS[key] = array
    return array


def aail_bounded_guard(
    request: ActRequest, group: StackedGroup, checked: CheckedRequest
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """What `aail_bounded` needs from the environment (`policy.regret_bound`), one
    `goal_reached` call for both: ε per row, (B,) (the request's, else
    `DEFAULT_EPSILON_PER_ALPHA` × the task network's training α; 0 where the ego's own goal is
    not reached yet, R2), and the rows, (B,) bool, whose goal is reached for good
    (`Domain.goal_is_final`: a served dish), where the task Q is flat (R3; None where no row
    is). (None, None) for the other methods."""
    if request.method != "aail_bounded":
        return None, None
    if request.regret_bound is not None:
        epsilon = float(request.regret_bound)
    else:
        epsilon = DEFAULT_EPSILON_PER_ALPHA * float(group.nets[0].alpha or DEFAULT_TEMPERATURE)
    domain = checked.runtime.domain
    reached = domain.goal_reached(checked.obs_BD, checked.n_agents, request.ego_goal)
    if reached is None:
        return np.full(checked.obs_BD.shape[0], epsilon), None
    reached_B = np.asarray(reached, dtype=bool)
    finished_B = reached_B if domain.goal_is_final and reached_B.any() else None
    return np.where(reached_B, epsilon, 0.0), finished_B


def budget_epsilon(request: ActRequest, group: StackedGroup) -> float:
    """aail_budget's per-step ε (R1, at every step): the request's `regret_bound`, else
    `BUDGET_EPSILON_PER_ALPHA` × the task network's training α."""
    if request.regret_bound is not None:
        return float(request.regret_bound)
    return BUDGET_EPSILON_PER_ALPHA * float(group.nets[0].alpha or DEFAULT_TEMPERATURE)


def spend_budget(
    request: ActRequest,
    checked: CheckedRequest,
    q_task_BA: np.ndarray,
    q_impact_BPA: np.ndarray,
    probs_blend_BA: np.ndarray,
    temperature: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """aail_budget's policy, (B, A), and the episode's spent S' and budget B, (B,) each
    (`policy.regret_budget`, eqs. B1-B4). At an episode's first step (no carried state) the
    budget is the request's fraction k (default `DEFAULT_BUDGET_FRACTION`) of the ego's task
    value here; later steps carry S and B from the last answer (k is then not read)."""
    probs_task_BA = boltzmann(q_task_BA, temperature)
    if checked.budget_total_B is None or checked.budget_spent_B is None:
        fraction = DEFAULT_BUDGET_FRACTION if request.budget is None else float(request.budget)
        total_B = initial_budget(probs_task_BA, q_task_BA, fraction)
        spent_B = np.zeros_like(total_B)
    else:
        total_B, spent_B = checked.budget_total_B, checked.budget_spent_B
    step = budget_rows(probs_task_BA, probs_blend_BA, q_task_BA, q_impact_BPA, spent_B, total_B)
    return step.probs_BA, step.spent_B, total_B


def goal_kept_of(
    request: ActRequest, checked: CheckedRequest, epsilon_B: np.ndarray | None
) -> np.ndarray | None:
    """(B, A) bool for R4 of `policy.regret_bound`: the actions that keep the ego's reached goal,
    on the rows where `aail_bounded` blends (ε > 0); every action elsewhere. None where nothing
    is to keep (another method, no row blending, or a goal that cannot be lost)."""
    if request.method != "aail_bounded" or epsilon_B is None or not (epsilon_B > 0.0).any():
        return None  # aail_budget's ε has no oracle behind it: R4 is aail_bounded's alone
    domain = checked.runtime.domain
    kept_BA = domain.goal_kept(checked.obs_BD, checked.n_agents, request.ego_goal)
    if kept_BA is None:
        return None
    return np.where((epsilon_B > 0.0)[:, None], kept_BA, True)
