"""Request and response bodies of the inference REST API (docs/architecture.md, "REST API").

| body              | route                | what                                                |
|-------------------|----------------------|-----------------------------------------------------|
| `ActBody`         | POST /v1/act         | one ego observation (or global state + ego index)   |
| `ActBatchBody`    | POST /v1/act:batch   | many observations (or states) with shared goals     |
| `ActResponse`     | POST /v1/act         | probabilities, sampled/greedy action, diagnostics   |
| `ActBatchResponse`| POST /v1/act:batch   | `{"results": [ActResponse, ...]}`, one per row      |
| `ActColumnsResponse` | POST /v1/act:batch | `"format": "columns"`: one array per field, B rows |
| `EnvsResponse`    | GET /v1/envs         | every environment's goals, layouts, action meanings |

The request models check only JSON types; the engine checks the values (lengths, goals, ranges)
and names the bad field. The response models document the JSON (OpenAPI); the routes write it
with orjson directly.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, Field

from services.rest.bounded import (
    MAX_LIST,
    GoalProbs,
    Matrix,
    RequestBody,
    Vector,
    VersionPins,
    at_most,
    bounded_list,
)
from services.rest.number_rows import NumberRows, NumberStates

MethodName = Literal["aail_bounded", "aail_budget", "aail", "nail", "sl", "jl"]
METHOD_HELP = (
    "blending method: aail_bounded (AAIL with a bound on the ego's own regret, the default), "
    "aail_budget (AAIL within an episode's regret budget: send back `budget_spent`, "
    "`budget_total` and `budget_value` from each answer), aail (the paper's eqs. 8-10), nail "
    "(plain average), sl "
    "(task network alone), jl (joint network)"
)
BUDGET_HELP = (
    "aail_budget only: the episode's budget B >= 0 of the ego's own task value, in the task "
    "network's Q units (default 8 times its training α); read at the first step only"
)
SPENT_HELP = (
    "aail_budget only: the `budget.spent` of the episode's last answer (leave out, with "
    "`budget_total` and `budget_value`, at the episode's first step)"
)
TOTAL_HELP = "aail_budget only: the `budget.total` of the episode's last answer"
VALUE_HELP = "aail_budget only: the `budget.value` of the episode's last answer"
REGRET_BOUND_HELP = (
    "aail_bounded only: ε >= 0, in the task network's Q units; actions whose task Q is more than "
    "ε below the best keep their task-policy probability (default: twice the task model's "
    "training α)"
)


class PartnerIn(RequestBody):
    index: int = Field(
        description="the partner's position in the ego's observation layout, 1..N-1 (with "
        "`state` input: agent j is at j + 1 if j < ego_index, else at j)"
    )
    goal: str | None = Field(default=None, description="the partner's announced goal")
    goal_probs: GoalProbs | None = Field(
        default=None,
        description="instead of `goal`: a distribution over goals (sums to 1)",
        examples=[{"b3": 0.7, "c": 0.3}],
    )


class ActFields(RequestBody):
    env: str = Field(description="environment name (see GET /v1/envs)", examples=["particle"])
    ego_goal: str = Field(description="the ego agent's goal", examples=["a2"])
    partners: Annotated[list[PartnerIn], bounded_list(MAX_LIST), at_most(MAX_LIST)] = Field(
        default_factory=list
    )
    method: MethodName = Field(default="aail_bounded", description=METHOD_HELP)
    temperature: float | None = Field(
        default=None, description="Boltzmann temperature > 0 (default: the model's training α)"
    )
    regret_bound: float | None = Field(default=None, description=REGRET_BOUND_HELP)
    budget: float | None = Field(default=None, description=BUDGET_HELP)
    seed: int | None = Field(default=None, description="seeds the sampled action(s)")
    alias: str = Field(default="production", description="alias every model is resolved by")
    versions: VersionPins = Field(
        default_factory=dict, description="pinned versions by model name (override the alias)"
    )
    ego_index: int | None = Field(
        default=None, description="with `state`/`states`: the ego's row in the global state"
    )


class ActBody(ActFields):
    observation: Vector | None = Field(
        default=None,
        description="the ego's observation in the env's documented layout",
        examples=[[0.1, 0.4, 0, 0, 0.7, 0.6, 0, 0]],
    )
    state: Matrix | None = Field(
        default=None, description="instead of `observation`: the global state, one row per agent"
    )
    budget_spent: float | None = Field(default=None, description=SPENT_HELP)
    budget_total: float | None = Field(default=None, description=TOTAL_HELP)
    budget_value: float | None = Field(default=None, description=VALUE_HELP)


class ActBatchBody(ActFields):
    observations: NumberRows | None = Field(
        default=None, description="the ego's observations, one per row"
    )
    states: NumberStates | None = Field(
        default=None, description="instead of `observations`: global states"
    )
    budget_spent: Vector | None = Field(default=None, description=SPENT_HELP + ", one per row")
    budget_total: Vector | None = Field(default=None, description=TOTAL_HELP + ", one per row")
    budget_value: Vector | None = Field(default=None, description=VALUE_HELP + ", one per row")
    format: Literal["rows", "columns"] = Field(
        default="rows",
        description="the response's form: `rows`, one result per observation (`results`), or "
        "`columns`, one array per field with the models listed once (tensors; far smaller "
        "and faster for large batches)",
    )


class PartnerWeight(BaseModel):
    index: int
    weight: float


class Diagnostics(BaseModel):
    task_entropy: float = Field(description="normalised entropy of the task policy")
    task_weight: float = Field(description="w_t (eq. 9; 1 for sl and jl)")
    partner_weights: list[PartnerWeight] = Field(description="normalised w_i per partner")


class BudgetOut(BaseModel):
    spent: float = Field(description="task value the episode has given up so far (eqs. B1-B4)")
    total: float = Field(description="the episode's budget; send all three back at the next step")
    value: float = Field(description="the ego's soft task value at this step (eq. B2)")


class ModelUsedOut(BaseModel):
    role: Literal["task", "impact", "joint", "monitor"]
    name: str
    version: int
    sha256: str
    partner_index: int | None
    goal: str


class ActResponse(BaseModel):
    probs: list[float]
    action: int = Field(description="sampled from `probs`")
    greedy_action: int
    action_meaning: str = Field(description="meaning of `action`")
    method: MethodName
    diagnostics: Diagnostics
    models: list[ModelUsedOut]
    budget: BudgetOut | None = Field(default=None, description="aail_budget only")


class ActBatchResponse(BaseModel):
    results: list[ActResponse]


class ActColumnsResponse(BaseModel):
    """A batch as columns: B rows, A actions, P partners; row b of each field is row b's answer."""

    format: Literal["columns"]
    method: MethodName
    models: list[ModelUsedOut] = Field(description="the models every row was computed with")
    probs: list[list[float]] = Field(description="B x A action probabilities")
    actions: list[int] = Field(description="B actions, each sampled from its row of `probs`")
    greedy_actions: list[int] = Field(description="B arg maxes of `probs`")
    action_meanings: list[str] = Field(description="B meanings, one per sampled action")
    task_entropies: list[float] = Field(description="B normalised task-policy entropies")
    task_weights: list[float] = Field(description="B task weights w_t")
    partner_indices: list[int] = Field(description="P partner indices, in request order")
    partner_weights: list[list[float]] = Field(
        description="B x P partner weights w_i, columns in `partner_indices` order"
    )
    budget_spent: list[float] | None = Field(default=None, description="aail_budget: B spent")
    budget_total: list[float] | None = Field(default=None, description="aail_budget: B budgets")
    budget_value: list[float] | None = Field(default=None, description="aail_budget: B task values")


class EnvOut(BaseModel):
    name: str
    goals: list[str]
    action_meanings: list[str]
    max_agents: int
    obs_dims: dict[str, int] = Field(description="agent count -> observation length")
    observation_layouts: dict[str, list[str]] = Field(
        description="agent count -> one name per observation feature"
    )
    state_layout: list[str] | None = Field(description="one agent's row of a global state")
    pair_obs_dim: int
    methods: list[MethodName]


class EnvsResponse(BaseModel):
    envs: list[EnvOut]
