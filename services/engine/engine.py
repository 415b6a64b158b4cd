"""`InferenceEngine`: the blended action distributions of paper §3.3 for B observation rows.
One engine per server process, shared by the REST and gRPC transports. An act reads top to
bottom in `_act`; every batch size takes the same steps (a single observation is B = 1).

| step     | what                                                          | where          |
|----------|---------------------------------------------------------------|----------------|
| check    | every field; bad ones -> `InvalidRequest(field, message)`     | `validation`   |
| resolve  | `{env}/task/{ego_goal}` and `{env}/impact/{g}` for every      | `planning`,    |
|          | partner goal g with probability > 0 (sl: the task net only;   | `model_cache`  |
|          | jl: `{env}/joint/{ego}+{p1}+...`, partners ordered by index), |                |
|          | by `name@alias` or a pinned version                           |                |
| stack    | the networks' weights, once per combination of versions       | `model_cache`  |
| inputs   | each member's input rows from the domain's views              | `planning`     |
| forward  | `networks.forward_group`: every member on its rows            | `networks`     |
| reduce   | task Q = mean over the K task views; one impact Q per partner,| `mean_views`,  |
|          | a goal distribution's the expectation over its goals (§3.2)   | `planning`     |
| blend    | `policy.blend.blend_checked` (eqs. 8-10; R1 for aail_bounded);| `policy.blend` |
|          | jl: the joint Q alone; aail_budget: AAIL's policy while the   | `spend_budget` |
|          | episode's budget lasts, the task's after (eqs. B1-B4)         |                |
| sample   | inverse CDF per row from `default_rng(seed)`, one stream over | `sample_rows`  |
|          | the rows (row r of a batch is not row 1 of a single request)  |                |

What a request's shape fixes (its networks, where each partner's Q-values lie, the models
used) is computed once and remembered in the engine's `planning.PlanCache`, which forgets
everything when the store's generation moves (a refresh that saw the store change).

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
in the store's next generation).

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

import logging
import threading
from collections.abc import Callable, Mapping, Sequence

import numpy as np

from envs.registry import known_envs
from model_store.errors import ModelStoreError
from model_store.naming import monitor_model_name
from model_store.store import ModelStore
from policy.blend import BlendMethod, blend_checked
from policy.maths import boltzmann, soft_value
from policy.regret_bound import DEFAULT_EPSILON_PER_ALPHA, MONITOR_KEEP_LOGIT, keep_goal_rows
from policy.regret_budget import DEFAULT_BUDGET_PER_ALPHA, budget_rows, initial_budget
from policy.row_forward import mean_views
from policy.sampling import sample_rows
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
from services.engine.networks import ROW_FORWARD, StackedGroup, forward_group, overflow_error
from services.engine.planning import (
    Layout,
    Needs,
    PlanCache,
    Plans,
    catalogue_plan,
    constant,
    impact_q,
    layout_of,
    member_inputs,
    plan_members,
)
from services.engine.validation import CheckedRequest, check_request

log = logging.getLogger(__name__)

# the method `blend_checked` runs for each method: aail_budget is the paper's AAIL while its
# budget lasts (B1-B4, `spend_budget`); sl and jl take the task (joint) network alone
BLEND_OF: dict[str, BlendMethod] = {
    "sl": "sl",
    "jl": "sl",
    "nail": "nail",
    "aail": "aail",
    "aail_bounded": "aail_bounded",
    "aail_budget": "aail",
}


class InferenceEngine:
    """Resolve, load, stack, evaluate, blend and sample (module docstring).

    `plans`: the memory of request plans and layouts (a new `PlanCache` if None).
    `numpy_forward`: numpy's forward even where the compiled one is built (the reference;
    then every request is served from its own group, `networks.forward_group`).
    `goal_oracle`: whether `aail_bounded` asks the environment whether the ego's goal is
    reached and which actions keep it (R2-R4, `aail_bounded_guard`); False serves it as in an
    environment whose observations cannot tell: what the blend is worth without those answers
    (`coexist eval --suite partners --no-goal-oracle`).
    `goal_monitors`: whether `aail_bounded` then asks the ego goal's monitor instead (where one
    is registered); False: R1 on every row (`--no-goal-monitor`)."""

    def __init__(
        self,
        store: ModelStore,
        *,
        cache_size: int = 256,
        stack_cache_size: int = 64,
        refresh_interval_s: float = 2.0,
        max_batch: int = 4096,
        plans: PlanCache | None = None,
        numpy_forward: bool = False,
        goal_oracle: bool = True,
        goal_monitors: bool = True,
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
        self.plans = PlanCache() if plans is None else plans
        self.numpy_forward = numpy_forward
        self.goal_oracle = goal_oracle
        self.goal_monitors = goal_monitors
        # whether a network's Q-values on a row are the same bits in any group and beside any
        # other rows (module docstring, "Goal distributions"): the compiled forward's are
        self.rows_independent = ROW_FORWARD and not numpy_forward
        self._rng = np.random.default_rng()  # for unseeded requests
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
        plans = self.plans.at(self.cache.generation)
        members, group = self._resolve_members(request, checked, plans, check_pins=public)
        layout: Layout = plans.remember(
            ("layout", group.key, members, checked.partners_key), layout_of, checked, members, group
        )
        inputs = member_inputs(checked, members, group, layout)
        q_members = forward_group(group, inputs, numpy_forward=self.numpy_forward)
        method, batch = request.method, checked.obs_BD.shape[0]
        monitors: list[ModelUsed] = []  # the goal monitor, where AAIL-B asked one
        monitor = None
        if method == "aail_bounded" and self.goal_monitors:

            def monitor() -> np.ndarray | None:
                return self._monitor_kept(request, checked, plans, inputs[0], monitors)

        epsilon_B, finished_B, kept_BA = aail_bounded_guard(
            request, group, checked, ask_domain=self.goal_oracle, monitor=monitor
        )
        q_task_BA = task_q(method, q_members[0], batch, finished_B)
        blend_method = BLEND_OF[method]
        if blend_method == "sl":  # the task/joint network alone: no impact network evaluated
            q_impact_BPA = np.zeros((batch, 0, checked.runtime.domain.n_actions))
        else:
            q_impact_BPA = impact_q(checked, q_members, layout)
        temperature = float(request.temperature or group.nets[0].alpha or DEFAULT_TEMPERATURE)
        # every partner slot is used, one temperature for all rows
        mask_BP = constant(plans, q_impact_BPA.shape[:2], True)
        temperature_B = constant(plans, (batch,), temperature)
        standardise = checked.runtime.domain.blend_normalisation == "standardise"
        try:
            blended = blend_checked(
                blend_method,
                q_task_BA,
                q_impact_BPA,
                mask_BP,
                temperature_B,
                standardise,
                epsilon_B,
            )
        except FloatingPointError:  # float32 outputs overflowed: on huge observations, or ...
            raise overflow_error(group, checked.obs_BD, "observations") from None
        probs_BA, spent_B, total_B = blended.probs_BA, None, None
        if kept_BA is not None:  # R4: no action that loses the reached goal where one keeps it
            probs_BA = keep_goal_rows(probs_BA, kept_BA)
        value_B = None
        if method == "aail_budget":
            probs_BA, spent_B, total_B, value_B = spend_budget(
                request, checked, group, q_task_BA, probs_BA, temperature
            )
        # one uniform per row, in order: row r of a batch is not row 1 of a single request
        rng = self._rng if request.seed is None else np.random.default_rng(request.seed)
        actions_B, greedy_B = sample_rows(probs_BA, rng.random((batch,)))
        return ActColumns(
            method=method,
            models=[*layout.models, *monitors],
            probs=probs_BA,
            actions=actions_B,
            greedy_actions=greedy_B,
            task_entropies=blended.task_entropy_B,
            task_weights=blended.task_weight_B,
            # sl and jl evaluated no impact network: every partner weighs 0
            partner_weights=np.zeros((batch, len(checked.partners)))
            if blend_method == "sl"
            else blended.partner_weights_BP,
            budget_spent=spent_B,
            budget_total=total_B,
            budget_value=value_B,
        )

    def _monitor_kept(
        self,
        request: ActRequest,
        checked: CheckedRequest,
        plans: Plans,
        task_rows: np.ndarray,
        used: list[ModelUsed],
    ) -> np.ndarray | None:
        """The actions, (B, A) bool, that the ego goal's monitor (`trainer.monitor`) says keep
        its goal, on the task views `task_rows` (B K rows; a logit mean over the K views), or
        None where no monitor is registered under the request's alias (remembered until the
        store's generation moves). Appends the monitor's `ModelUsed` to `used`."""
        domain = checked.runtime.domain
        key = ("monitor", domain.name, request.ego_goal, request.alias)
        if plans.get(key) is False:
            return None
        name = monitor_model_name(domain.name, request.ego_goal)
        needs: Needs = plans.remember(
            ("monitor needs", name), lambda: ((name, "ego_goal", "no goal monitor"),)
        )
        members: tuple[Member, ...] = plans.remember(
            ("monitor members", name), lambda: (("monitor", request.ego_goal),)
        )
        try:
            _, group = self.cache.resolve_group(needs, request.alias, {}, members, domain)
        except ModelNotFound:
            plans.put(key, False)
            return None
        q = forward_group(group, [task_rows], numpy_forward=self.numpy_forward)
        logits_BA = mean_views(q[0], len(task_rows) // checked.obs_BD.shape[0])
        net = group.nets[0]
        used.append(ModelUsed("monitor", net.name, net.version, net.sha256, None, request.ego_goal))
        return np.asarray(logits_BA > MONITOR_KEEP_LOGIT)

    def _resolve_members(
        self, request: ActRequest, checked: CheckedRequest, plans: Plans, *, check_pins: bool
    ) -> tuple[tuple[Member, ...], StackedGroup]:
        """The networks the request needs (`planning.plan_members`) and their stacked group,
        resolved in order (so the first missing one is the one reported). A remembered plan is
        the same tuple each time, so the cache resolves it as one fixed set
        (`ModelCache.resolve_group`). `check_pins`: a pinned version of a model the request
        does not use is an error (a pin that silently does nothing hides a typo)."""
        shape = (
            checked.runtime.domain.name,
            request.method,
            request.ego_goal,
            checked.partners_key,
        )
        members, needs = plans.remember(("members", *shape), plan_members, request, checked)
        if check_pins and request.versions:
            _check_pins_used(request.versions, needs)
        if self._with_distributions(request, checked):
            served = self._distributions_group(request, checked, plans, shape, members, needs)
            if served is not None:
                return served
        _, group = self.cache.resolve_group(
            needs, request.alias, request.versions, members, checked.runtime.domain
        )
        return members, group

    def _with_distributions(self, request: ActRequest, checked: CheckedRequest) -> bool:
        """Whether every goal's group may serve the request (module docstring, "Goal
        distributions"): a blend of impact networks, a partner given as a goal distribution,
        no pinned version, and rows that are independent (`rows_independent`)."""
        for partner in checked.partners:  # a loop, not any(): most requests announce every goal
            if partner.probs is not None:
                break
        else:
            return False
        return BLEND_OF[request.method] != "sl" and not request.versions and self.rows_independent

    def _distributions_group(
        self,
        request: ActRequest,
        checked: CheckedRequest,
        plans: Plans,
        shape: tuple[object, ...],
        members: tuple[Member, ...],
        needs: Needs,
    ) -> tuple[tuple[Member, ...], StackedGroup] | None:
        """Where a request with a partner given as a goal distribution is served from (module
        docstring, "Goal distributions"): its own group when that is stacked; else every
        goal's group, unless its own is small and asked for before without being stacked
        (then None: stack it). None also where every goal's group cannot serve."""
        group = self.cache.cached_group(needs, request.alias, members)
        if group is not None:
            return members, group
        seen = plans.get(("seen", *shape))  # None, "seen" or "stacked"
        small = len(members) - 1 <= len(checked.runtime.domain.goals) // 4
        if seen == "seen" and small:  # asked for again: its own forward is worth a stack
            plans.put(("seen", *shape), "stacked")
            return None
        if seen is None:
            plans.put(("seen", *shape), "seen")
        return self._catalogue_group(request, checked, plans, len(members))

    def _catalogue_group(
        self, request: ActRequest, checked: CheckedRequest, plans: Plans, own_members: int
    ) -> tuple[tuple[Member, ...], StackedGroup] | None:
        """The stacked group of the task network and EVERY goal's impact network, or None:
        the request's own networks are those already, or one of every goal's is missing or
        cannot be loaded (then not tried again in this store generation)."""
        domain = checked.runtime.domain
        key = ("catalogue", domain.name, request.method, request.ego_goal, request.alias)
        plan = plans.remember(key, catalogue_plan, request, checked)
        if plan.missing or own_members == len(plan.members):  # missing, or the same group
            return None
        try:
            _, group = self.cache.resolve_group(plan.needs, request.alias, {}, plan.members, domain)
        except (ModelNotFound, ModelUnavailable):  # the request's own networks may serve:
            # not tried again before the store changes (a failing load per request would cost
            # more than the groups it saves; the request's own path reports its own errors)
            plans.put(key, plan._replace(missing=True))
            return None
        self.stats.catalogue_group_acts += 1
        return plan.members, group

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
        noise: float = 0.0,
    ) -> np.ndarray:
        """(P, G) log π_g(actions[p] | partner p's view of the ego's `observation`), goals in
        the env's catalogue order: every task network in one stacked pass; `noise` η > 0 mixes
        each policy with uniform action noise, log((1 - η) π_g + η / A)."""
        return goal_log_likelihoods(
            self.cache,
            env,
            observation,
            partners,
            actions,
            alias=alias,
            versions=versions,
            temperature=temperature,
            noise=noise,
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


def _check_pins_used(pinned: Mapping[str, int], needs: Sequence[tuple[str, str, str]]) -> None:
    used = [name for name, _, _ in needs]
    for name in pinned:
        if name not in used:
            raise InvalidRequest(
                f"versions[{name}]",
                f"this request uses no model {name!r} (it uses {', '.join(used)}): a pin must "
                "name one of them",
            )


def task_q(
    method: str, q_task_RA: np.ndarray, batch: int, finished_B: np.ndarray | None
) -> np.ndarray:
    """The task Q, (B, A) float64: the joint network's own (jl), else the task network's
    averaged over the K task views of each row (one per other agent); flat on the rows whose
    goal is reached for good (`finished_B`, R3: nothing left to earn)."""
    if method == "jl":
        return q_task_RA.astype(np.float64)
    q_task_BA = mean_views(q_task_RA, q_task_RA.shape[0] // batch)
    if finished_B is not None:
        flat_BA = np.broadcast_to(q_task_BA.mean(axis=1, keepdims=True), q_task_BA.shape)
        q_task_BA = np.where(finished_B[:, None], flat_BA, q_task_BA)
    return q_task_BA


def aail_bounded_guard(
    request: ActRequest,
    group: StackedGroup,
    checked: CheckedRequest,
    *,
    ask_domain: bool = True,
    monitor: Callable[[], np.ndarray | None] | None = None,
) -> tuple[np.ndarray | None, np.ndarray | None, np.ndarray | None]:
    """What `aail_bounded` needs from the environment (`policy.regret_bound`), from one
    `goal_reached` call and, where a row's goal is reached, one `goal_kept` call (neither
    where `ask_domain` is False). Where the domain cannot tell (or is not asked), the ego goal's
    monitor answers both, `monitor()`: the actions it says keep the goal are K (R4) and the goal
    is reached where K is not empty (R2); without a monitor, ε on every row:

    - ε per row, (B,): the request's, else `DEFAULT_EPSILON_PER_ALPHA` × the task network's
      training α; 0 where the ego's own goal is not reached yet (R2);
    - the rows, (B,) bool, whose task Q is flat (R3): ε > 0 and the goal reached for good
      (`Domain.goal_is_final`: a served dish) or reached with an action that keeps it; None
      where no row is;
    - the actions, (B, A) bool, that keep a reached goal on the rows that blend (R4; every
      action elsewhere); None where nothing is to keep.

    (None, None, None) for the other methods."""
    if request.method != "aail_bounded":
        return None, None, None
    if request.regret_bound is not None:
        epsilon = float(request.regret_bound)
    else:
        epsilon = DEFAULT_EPSILON_PER_ALPHA * float(group.nets[0].alpha or DEFAULT_TEMPERATURE)
    domain = checked.runtime.domain
    batch = checked.obs_BD.shape[0]
    reached = (
        domain.goal_reached(checked.obs_BD, checked.n_agents, request.ego_goal)
        if ask_domain
        else None
    )
    kept: np.ndarray | None = None
    if reached is None and monitor is not None:
        kept = monitor()
        if kept is not None:
            reached = np.asarray(kept.any(axis=1))
    if reached is None:
        return np.full(batch, epsilon), None, None
    blending_B = np.asarray(reached, dtype=bool) & (epsilon > 0.0)
    if not blending_B.any():
        return np.zeros(batch), None, None
    epsilon_B = np.where(blending_B, epsilon, 0.0)
    if kept is None and domain.goal_is_final:
        return epsilon_B, blending_B, None
    if kept is None:
        kept = domain.goal_kept(checked.obs_BD, checked.n_agents, request.ego_goal)
    if kept is None:
        return epsilon_B, None, None
    kept_BA = np.where(blending_B[:, None], np.asarray(kept, dtype=bool), True)
    flat_B = blending_B & kept_BA.any(axis=1)
    return epsilon_B, (flat_B if flat_B.any() else None), kept_BA


def spend_budget(
    request: ActRequest,
    checked: CheckedRequest,
    group: StackedGroup,
    q_task_BA: np.ndarray,
    probs_blend_BA: np.ndarray,
    temperature: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """aail_budget's policy, (B, A), and the episode's state after this step, (B,) each: spent
    S', budget B and the ego's task value V here (`policy.regret_budget`, eqs. B1-B4). At an
    episode's first step (no carried state) B is the request's `budget`, else
    `DEFAULT_BUDGET_PER_ALPHA` × the task network's training α, and nothing is spent; later
    steps carry S, B and V from the last answer (`budget` is then not read)."""
    probs_task_BA = boltzmann(q_task_BA, temperature)
    value_B = soft_value(q_task_BA, temperature)
    spent_B, total_B, last_B = (
        checked.budget_spent_B,
        checked.budget_total_B,
        checked.budget_value_B,
    )
    if spent_B is None or total_B is None or last_B is None:
        if request.budget is not None:
            budget = float(request.budget)
        else:
            budget = DEFAULT_BUDGET_PER_ALPHA * float(group.nets[0].alpha or DEFAULT_TEMPERATURE)
        total_B = initial_budget(budget, len(value_B))
        spent_B, last_B = np.zeros_like(total_B), value_B
    step = budget_rows(probs_task_BA, probs_blend_BA, q_task_BA, value_B, spent_B, total_B, last_B)
    return step.probs_BA, step.spent_B, total_B, value_B
