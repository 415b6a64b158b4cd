"""`InferenceEngine`: the blended action distributions of paper §3.3 for B observation rows.
One engine per server process, shared by the REST and gRPC transports.

| step     | what                                                          | where          |
|----------|---------------------------------------------------------------|----------------|
| check    | every field; bad ones -> `InvalidRequest(field, message)`     | `validation`   |
| resolve  | `{env}/task/{ego_goal}` and `{env}/impact/{g}` for every      | `model_cache`  |
|          | partner goal g with probability > 0 (sl: the task net only;   |                |
|          | jl: `{env}/joint/{ego}+{p1}+...`, partners ordered by index), |                |
|          | by `name@alias` or a pinned version                           |                |
| stack    | the networks' weights, once per combination of versions       | `model_cache`  |
| forward  | one `numpy_stacked_forward` over all members (task net on its | `networks`,    |
|          | K task views, each impact net on its partners' impact views)  | `assembly`     |
| blend    | `policy.blend.blend` (eqs. 8-10) on the task Q (mean over the |                |
|          | K views) and one impact Q per partner; jl: the joint Q alone  |                |
| sample   | inverse CDF per row from `default_rng(seed)`, one stream over | `assembly`     |
|          | the rows (row r of a batch is not row 1 of a single request)  |                |
| infer    | partners' actions under all G task nets, one pass (issue 9)   | `goal_inference`|

A single observation row with sl, nail or aail takes `fastpath.act_row` after the stack step:
the same steps with few numpy calls and Python floats (3-4x faster at batch 1; numbers
equal up to float32 rounding). The general path builds its answer as arrays (`ActColumns`, what
`act_columns` returns; `act` makes the rows of them); the fast path's row becomes columns by
`ActColumns.from_results`. The networks a request shape needs (`_plan_members`) are
remembered; resolution and stacking go through `model_cache` on every request (a remembered
plan as one fixed set: `ModelCache.resolve_group`), so hot reload, the stacks' LRU order and the
cache counters are those of the general path.

Choices the paper leaves open: the temperature is the request's, else the task (jl: joint)
model's training α (`lineage.config["alpha"]`), else 0.02. Whether AAIL standardises the
Q-vectors before eq. 8 is the environment's `Domain.blend_normalisation` (`policy.blend`). For jl the "task" diagnostics describe
the joint policy (`task_weight` 1, partner weights 0); jl needs each partner's announced goal.
Partners given with `sl` are checked but load no network.

Hot reload: `refresh()` (or the daemon thread of `start_refresh_thread`, every
`refresh_interval_s`) swaps moved aliases to their new versions, loaded before the swap; see
`model_cache`.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Mapping, Sequence

import numpy as np

from envs.registry import known_envs
from model_store.errors import InvalidArgument, ModelStoreError
from model_store.naming import joint_model_name
from model_store.store import ModelStore
from policy.blend import BlendMethod, blend
from policy.regret_bound import keep_goal_rows
from services.engine.assembly import (
    finished_rows,
    goal_kept_of,
    impact_q,
    member_inputs,
    models_used,
    regret_bound_of,
    sample_actions,
)
from services.engine.environments import env_runtime
from services.engine.errors import EngineError, InvalidRequest
from services.engine.fastpath import act_row
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
)
from services.engine.model_cache import ModelCache
from services.engine.networks import StackedGroup, forward_group
from services.engine.validation import CheckedRequest, check_request

log = logging.getLogger(__name__)

MEMBER_PLANS_MAX = 1024  # request shapes remembered (the table is cleared when full)


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
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    # --- act -------------------------------------------------------------------------------
    def act(self, request: ActRequest) -> list[ActResult]:
        """One result per observation row; `EngineError` on bad input or missing models."""
        return self.act_checked(request, None)

    def act_columns(self, request: ActRequest) -> ActColumns:
        """`act`'s results as columns (one array per field, the models once): the same values,
        sampled actions, errors and stats; `act_columns(r).rows()` equals `act(r)`."""
        answer = self._counted(request, None)
        return answer if isinstance(answer, ActColumns) else ActColumns.from_results(answer)

    def act_checked(self, request: ActRequest, checked: CheckedRequest | None) -> list[ActResult]:
        """`act`, given what `check_request(request)` would return (None: check it here).
        Internal, for a caller that checked the request's parts itself and builds `checked`
        from them (a session: settings once, the observation and its belief's distribution on
        each step); `request.observations` and `request.partners` are then not read."""
        answer = self._counted(request, checked)
        return answer if isinstance(answer, list) else answer.rows()

    def _counted(
        self, request: ActRequest, checked: CheckedRequest | None
    ) -> list[ActResult] | ActColumns:
        try:
            answer = self._act(request, checked)
        except EngineError:
            self.stats.errors += 1
            raise
        self.stats.requests += 1
        self.stats.rows += len(answer)
        return answer

    def _act(
        self, request: ActRequest, checked: CheckedRequest | None
    ) -> list[ActResult] | ActColumns:
        """The single-row fast path's rows, else the general path's columns (each converts to
        the other only when asked for it: `act` wants rows, `act_columns` columns)."""
        public = checked is None  # a transport's request, not a session's (which checks its own)
        if checked is None:
            checked = check_request(request, self.max_batch)
        domain, method = checked.runtime.domain, request.method
        members, group = self._resolve_members(request, checked, check_pins=public)
        batch, n_actions = checked.obs_BD.shape[0], domain.n_actions
        if batch == 1 and method != "jl":
            results = act_row(checked, request, members, group, self._rng)
            if results is not None:
                return results
        inputs, layout = member_inputs(checked, members, group)
        q_members = forward_group(group, inputs)
        if method == "jl":
            q_task_BA = q_members[0]
        else:  # the task Q averaged over the K task views (one per other agent)
            q_task_BA = q_members[0].reshape(batch, -1, n_actions).mean(axis=1)
        finished_B = finished_rows(request, checked)
        if finished_B is not None:  # R3: nothing left to earn, the exact task Q is flat
            flat_BA = np.broadcast_to(q_task_BA.mean(axis=1, keepdims=True), q_task_BA.shape)
            q_task_BA = np.where(finished_B[:, None], flat_BA, q_task_BA)
        blend_method: BlendMethod = "sl"
        q_impact_BPA = np.zeros((batch, 0, n_actions))  # sl, jl: the task/joint network alone
        if method in ("nail", "aail", "aail_bounded"):
            blend_method = method
            q_impact_BPA = impact_q(checked, q_members, layout)
        if not (np.isfinite(q_task_BA).all() and np.isfinite(q_impact_BPA).all()):
            raise InvalidRequest("observations", "values so large that the Q-values overflow")
        temperature = request.temperature or group.nets[0].alpha or DEFAULT_TEMPERATURE
        normalise = checked.runtime.domain.blend_normalisation == "standardise"
        epsilon_B = regret_bound_of(request, group, checked)
        blended = blend(
            blend_method,
            q_task_BA,
            q_impact_BPA,
            temperature,
            normalise=normalise,
            regret_bound=epsilon_B,
        )
        partner_weights_BP = blended.partner_weights_BP
        if blend_method == "sl":  # no impact network was evaluated: every partner weighs 0
            partner_weights_BP = np.zeros((batch, len(checked.partners)))
        rng = self._rng if request.seed is None else np.random.default_rng(request.seed)
        probs_BA = np.asarray(blended.probs_BA, dtype=np.float64)
        kept_BA = goal_kept_of(request, checked, epsilon_B)
        if kept_BA is not None:  # R4: no action that loses the reached goal where one keeps it
            probs_BA = keep_goal_rows(probs_BA, kept_BA)
        return ActColumns(
            method=method,
            models=models_used(checked, members, group),
            probs=probs_BA,
            actions=sample_actions(probs_BA, rng).astype(np.int64, copy=False),
            greedy_actions=probs_BA.argmax(axis=1).astype(np.int64, copy=False),
            task_entropies=np.asarray(blended.task_entropy_B, dtype=np.float64),
            task_weights=np.asarray(blended.task_weight_B, dtype=np.float64),
            partner_weights=np.asarray(partner_weights_BP, dtype=np.float64),
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
            tuple((p.index, p.goals, p.probs is None) for p in checked.partners),
        )
        plan = self._member_plans.get(key)
        if plan is None:
            plan = _plan_members(request, checked)
            if len(self._member_plans) >= MEMBER_PLANS_MAX:
                self._member_plans.clear()
            self._member_plans[key] = plan
        members, needs = plan
        if check_pins and request.versions:
            _check_pins_used(request.versions, needs)
        _, group = self.cache.resolve_group(
            needs, request.alias, request.versions, members, checked.runtime.domain
        )
        return members, group

    # --- goal inference (issue 9; `goal_inference`) -----------------------------------------
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


def _check_pins_used(pinned: Mapping[str, int], needs: Sequence[tuple[str, str, str]]) -> None:
    used = [name for name, _, _ in needs]
    for name in pinned:
        if name not in used:
            raise InvalidRequest(
                f"versions[{name}]",
                f"this request uses no model {name!r} (it uses {', '.join(used)}): a pin must "
                "name one of them",
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
