"""What goes into and comes out of the engine: plain frozen dataclasses (docs/architecture.md).

| class          | what                                                                   |
|----------------|------------------------------------------------------------------------|
| `PartnerSpec`  | one partner: its index in the ego's observation layout and its goal    |
|                | (one announced `goal`, or `goal_probs`, a distribution over goals)     |
| `ActRequest`   | env, ego goal, observations (B, obs_dim), partners, method, temperature,|
|                | regret bound, budget state, seed, alias and pinned versions            |
| `ModelUsed`    | one network a result was computed with (name, version, sha256, role)   |
| `ActResult`    | one per observation row: probabilities, sampled and greedy action,     |
|                | blend diagnostics, models used                                         |
| `ActColumns`   | the same for a whole batch as arrays, one per field (method and models |
|                | once): `rows()` gives the `ActResult`s                                 |
| `EnvInfo`      | one environment as `GET /v1/envs` describes it                         |
| `EngineStatus` | readiness: store reachable, models loaded, versions served             |
| `EngineStats`  | counters for metrics (cache hits and misses, loads, reloads ...)       |
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

Method = Literal["aail_bounded", "aail_budget", "aail", "nail", "sl", "jl"]
METHODS: tuple[Method, ...] = ("aail_bounded", "aail_budget", "aail", "nail", "sl", "jl")
Role = Literal["task", "impact", "joint", "monitor"]
Member = tuple[Role, str]  # one network a request needs: its role and the goal it serves
DEFAULT_ALIAS = "production"
DEFAULT_METHOD: Method = "aail_bounded"  # measured: reports/paper/REPORT.md
DEFAULT_TEMPERATURE = 0.02  # used when neither the request nor the model's lineage gives one


@dataclass(frozen=True)
class PartnerSpec:
    index: int  # the partner's position in the ego's observation layout (1..N-1)
    goal: str | None = None  # the announced goal, or
    goal_probs: Mapping[str, float] | None = None  # a distribution over goals (exactly one of two)


@dataclass(frozen=True, eq=False)  # eq=False: `observations` is an array
class ActRequest:
    env: str
    ego_goal: str
    observations: np.ndarray  # (B, obs_dim): the ego's observations (B = 1 for /v1/act)
    partners: tuple[PartnerSpec, ...] = ()
    method: Method = DEFAULT_METHOD
    temperature: float | None = None  # default: the task (or joint) model's training α
    regret_bound: float | None = None  # aail_bounded's ε; default: twice the task model's α
    # aail_budget (`policy.regret_budget`): the episode's budget B in the task network's value
    # units (default DEFAULT_BUDGET_PER_ALPHA × its α), and the episode's state carried from its
    # last step, per row (B,): S spent so far, the budget B and the ego's task value V at that
    # step (all three None at the episode's first step)
    budget: float | None = None
    budget_spent: Sequence[float] | np.ndarray | None = None
    budget_total: Sequence[float] | np.ndarray | None = None
    budget_value: Sequence[float] | np.ndarray | None = None
    seed: int | None = None  # seeds the sampled action(s); one stream over the B rows
    alias: str = DEFAULT_ALIAS  # the alias every model is resolved by
    versions: Mapping[str, int] = field(default_factory=dict)  # pinned versions by model name


@dataclass(frozen=True)
class ModelUsed:
    role: Role
    name: str
    version: int
    sha256: str
    partner_index: int | None  # None for the task and joint networks
    goal: str  # the goal the network serves (for a joint network: the ego's)


@dataclass(slots=True)  # read-only by convention: a frozen dataclass's __init__ is several
class ActResult:  # times dearer, and a batch makes one per row (docs/performance.md)
    probs: list[float]
    action: int  # sampled from `probs`
    greedy_action: int  # arg max of `probs` (the first on ties)
    method: str
    task_entropy: float  # normalised entropy of the task policy (of the joint policy for jl)
    task_weight: float  # w_t (1 for sl and jl)
    partner_weights: list[float]  # one per partner, in `partners` order
    models: list[ModelUsed]
    budget_spent: float | None = None  # aail_budget: S after this step (eqs. B3-B4)
    budget_total: float | None = None  # aail_budget: the episode's budget B
    budget_value: float | None = None  # aail_budget: the ego's task value V at this step


@dataclass(frozen=True, eq=False)  # eq=False: the fields are arrays
class ActColumns:
    """A batch's results as columns: B rows, A actions, P partners (`InferenceEngine.act_columns`)."""

    method: str
    models: list[ModelUsed]  # every row was computed with these
    probs: np.ndarray  # (B, A) float64
    actions: np.ndarray  # (B,) int64, sampled from `probs`
    greedy_actions: np.ndarray  # (B,) int64, arg max of `probs` (the first on ties)
    task_entropies: np.ndarray  # (B,) float64
    task_weights: np.ndarray  # (B,) float64
    partner_weights: np.ndarray  # (B, P) float64, partners in request order
    budget_spent: np.ndarray | None = None  # (B,) aail_budget's S after this step, else None
    budget_total: np.ndarray | None = None  # (B,) aail_budget's episode budget B, else None
    budget_value: np.ndarray | None = None  # (B,) aail_budget's task value V here, else None

    def __len__(self) -> int:
        return len(self.probs)

    def rows(self) -> list[ActResult]:
        """One `ActResult` per row (each with its own copy of the model list)."""
        probs, actions = self.probs.tolist(), self.actions.tolist()
        greedy, entropy = self.greedy_actions.tolist(), self.task_entropies.tolist()
        w_task, w_partners = self.task_weights.tolist(), self.partner_weights.tolist()
        method, models = self.method, self.models
        spent: list[float | None] = [None] * len(probs)
        total: list[float | None] = [None] * len(probs)
        value: list[float | None] = [None] * len(probs)
        if (
            self.budget_spent is not None
            and self.budget_total is not None
            and self.budget_value is not None
        ):
            spent, total = self.budget_spent.tolist(), self.budget_total.tolist()
            value = self.budget_value.tolist()
        return [
            ActResult(
                probs[b],
                actions[b],
                greedy[b],
                method,
                entropy[b],
                w_task[b],
                w_partners[b],
                list(models),
                spent[b],
                total[b],
                value[b],
            )
            for b in range(len(probs))
        ]

    @classmethod
    def from_results(cls, results: Sequence[ActResult]) -> ActColumns:
        """The columns of `results` (at least one; the first row's method and models)."""
        if not results:
            raise ValueError("results: expected at least one row")
        first = results[0]
        return cls(
            method=first.method,
            models=list(first.models),
            probs=np.array([r.probs for r in results], dtype=np.float64),
            actions=np.array([r.action for r in results], dtype=np.int64),
            greedy_actions=np.array([r.greedy_action for r in results], dtype=np.int64),
            task_entropies=np.array([r.task_entropy for r in results], dtype=np.float64),
            task_weights=np.array([r.task_weight for r in results], dtype=np.float64),
            partner_weights=np.array(
                [r.partner_weights for r in results], dtype=np.float64
            ).reshape(len(results), len(first.partner_weights)),
            budget_spent=None
            if first.budget_spent is None
            else np.array([r.budget_spent for r in results], dtype=np.float64),
            budget_total=None
            if first.budget_total is None
            else np.array([r.budget_total for r in results], dtype=np.float64),
            budget_value=None
            if first.budget_value is None
            else np.array([r.budget_value for r in results], dtype=np.float64),
        )


@dataclass(frozen=True)
class EnvInfo:
    name: str
    goals: tuple[str, ...]
    action_meanings: tuple[str, ...]
    max_agents: int
    obs_dims: dict[int, int]  # agent count -> observation length
    observation_layouts: dict[int, list[str]]  # agent count -> one name per feature
    state_layout: tuple[str, ...] | None  # one agent's row of a global state, None: no state input
    pair_obs_dim: int
    methods: tuple[str, ...]


@dataclass(frozen=True)
class EngineStatus:
    store_reachable: bool
    store_error: str | None  # why the store is not reachable
    models_loaded: int  # networks in the weights cache
    versions_served: dict[str, int]  # "name@alias" -> version, for every alias resolved so far
    change_token: str | None  # the store change token the served versions reflect
    refresh_thread_alive: bool


@dataclass
class EngineStats:
    """Monotonic counters (read them, never reset). Increments from request threads are not
    locked, so under heavy contention a count may be off by a few: fine for metrics."""

    requests: int = 0  # act() calls that returned results
    rows: int = 0  # observation rows answered
    errors: int = 0  # act() calls that raised an EngineError
    resolve_hits: int = 0  # name@alias served from the resolution cache
    resolve_misses: int = 0
    cache_hits: int = 0  # networks found in the weights cache
    cache_misses: int = 0
    stack_hits: int = 0  # stacked network groups found ready
    stack_misses: int = 0
    loads: int = 0  # networks loaded (and sha256-verified) from the store
    load_failures: int = 0
    refreshes: int = 0  # refresh() calls that saw a new store change token
    reloads: int = 0  # aliases that moved and were swapped to their new version
    refresh_errors: int = 0  # refresh() calls that failed (store down ...) and will be retried
    likelihood_passes: int = 0  # goal-likelihood passes over every task net, the actions known
    likelihood_tables: int = 0  # the same passes for every action, ahead (a session's next step)
    likelihood_tables_used: int = 0  # session steps whose evidence such a table scored
    catalogue_group_acts: int = 0  # acts whose goal distributions every goal's group served
    pruned_updates: int = 0  # belief rows updated with goal pruning (some goals not scored)
    pruned_rescored: int = 0  # pruning rows whose bound exceeded δ: every goal scored then

    def snapshot(self) -> EngineStats:
        return EngineStats(**vars(self))
