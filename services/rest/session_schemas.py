"""Request and response bodies of the session routes (docs/architecture.md, "Sessions").

| body              | route                              | what                                    |
|-------------------|------------------------------------|-----------------------------------------|
| `SessionBody`     | POST /v1/sessions                  | /v1/act's settings; partners may infer  |
| `SessionOut`      | POST /v1/sessions, GET /v1/sessions/{id} | id, next step, beliefs, expiry    |
| `SessionStepBody` | POST /v1/sessions/{id}/steps       | one observation (or state) + `observed` |
| `SessionStepOut`  | POST /v1/sessions/{id}/steps       | /v1/act's answer + step and beliefs     |

As for /v1/act, the models check JSON types only; the session checks the values and names the
bad field.
"""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

from policy.belief import DEFAULT_NOISE
from services.rest.bounded import (
    MAX_LIST,
    Matrix,
    RequestBody,
    Vector,
    VersionPins,
    at_most,
    bounded_list,
)
from services.rest.schemas import (
    METHOD_HELP,
    REGRET_BOUND_HELP,
    ActResponse,
    MethodName,
    PartnerIn,
)


# The session bodies are strict: JSON numbers stay numbers and booleans booleans (`"floor":
# false` or `"index": "1"` is refused, not coerced); an integer is still a valid number.
class SessionPartnerIn(PartnerIn):
    model_config = ConfigDict(extra="forbid", strict=True)

    infer: bool = Field(
        default=False,
        description="infer the partner's goal from its observed actions; a given `goal` or "
        "`goal_probs` is then the belief's prior (a partner with neither is inferred from a "
        "uniform prior)",
    )


class BeliefIn(RequestBody):
    model_config = ConfigDict(extra="forbid", strict=True)

    forgetting: float = Field(
        default=0.95,
        description="λ in (0, 1]: per step the belief is pulled back toward the prior by 1 - λ "
        "(partners change their minds); 1 = plain Bayes",
    )
    floor: float = Field(
        default=1e-3, description="ε in [0, 1/G): every goal keeps probability >= ε"
    )
    temperature: float | None = Field(
        default=None,
        description="α of the partners' Boltzmann policies (default: `LIKELIHOOD_TEMPERING` "
        "times each task model's training α)",
    )
    noise: float = Field(
        default=DEFAULT_NOISE,
        description="η in [0, 1): the likelihood expects this share of a partner's actions to "
        "be uniformly random, (1 - η) π_g(a | s) + η / |A|, so that no single unexpected action "
        "rules a goal out; 0: the plain Boltzmann policy",
    )
    blend_mass: float = Field(
        default=1.0,
        description="the blend mixes the impact networks of the most probable goals covering "
        "this mass of the belief, in (0, 1]; 1 (default): every goal, the exact expected impact "
        "Q, with the same networks at every step. Below 1 the set of goals changes as the "
        "belief moves: the server then evaluates every goal's network and mixes the kept "
        "ones (about the cost of 1)",
    )
    blend_max_goals: int | None = Field(
        default=None,
        description="at most this many goals in the blend (null, default: no bound); a bound "
        "below the number of goals costs what blend_mass below 1 costs",
    )
    prune_below: float = Field(
        default=0.0,
        description="τ: goal pruning, 0 (default) = off. Goals below this probability (but "
        "each partner's most probable) are neither scored by the belief update nor blended, "
        "in (floor, 1]; a step whose error bound exceeds prune_error scores every goal",
    )
    prune_error: float = Field(
        default=0.05,
        description="δ in (0, 1]: pruning scores only the likely goals while the bound on the "
        "step's total-variation error of the belief is at most this",
    )


class SessionBody(RequestBody):
    model_config = ConfigDict(extra="forbid", strict=True)

    env: str = Field(description="environment name (see GET /v1/envs)", examples=["particle"])
    ego_goal: str = Field(description="the ego agent's goal", examples=["a2"])
    partners: Annotated[list[SessionPartnerIn], bounded_list(MAX_LIST), at_most(MAX_LIST)] = Field(
        default_factory=list, examples=[[{"index": 1, "infer": True}]]
    )
    method: MethodName = Field(default="aail_bounded", description=METHOD_HELP)
    temperature: float | None = Field(
        default=None, description="Boltzmann temperature > 0 of the act (default: the model's α)"
    )
    regret_bound: float | None = Field(default=None, description=REGRET_BOUND_HELP)
    budget: float | None = Field(
        default=None,
        description="aail_budget only: the episode's budget B >= 0 of the ego's own task value, "
        "in the task network's Q units (default 8 times its training α); the session carries "
        "what it spent from step to step",
    )
    seed: int | None = Field(default=None, description="step t samples with seed + t")
    alias: str = Field(default="production", description="alias every model is resolved by")
    versions: VersionPins = Field(
        default_factory=dict, description="pinned versions by model name (override the alias)"
    )
    belief: BeliefIn = Field(default_factory=BeliefIn)


class ObservedIn(RequestBody):
    model_config = ConfigDict(extra="forbid", strict=True)

    index: int = Field(description="an inferred partner's index")
    action: int | None = Field(
        default=None,
        description="the action the partner took since the previous step; null: the server "
        "recovers it from the previous and this observation (envs that can)",
    )


class SessionStepBody(RequestBody):
    model_config = ConfigDict(extra="forbid", strict=True)

    observation: Vector | None = Field(
        default=None,
        description="the ego's observation o_t (see POST /v1/act)",
        examples=[[0.1, 0.4, 0, 0, 0.7, 0.6, 0, 0]],
    )
    state: Matrix | None = Field(
        default=None, description="instead of `observation`: the global state, one row per agent"
    )
    ego_index: int | None = Field(default=None, description="with `state`: the ego's row")
    observed: Annotated[list[ObservedIn], bounded_list(MAX_LIST), at_most(MAX_LIST)] = Field(
        default_factory=list,
        examples=[[{"index": 1, "action": 3}]],
        description="the actions a_{t-1} partners took between the previous observation and "
        "this one (none at step 0)",
    )
    expected_step: int | None = Field(
        default=None,
        description="refuse (409) unless this is the session's next step: a retry of an "
        "answered step then does not count twice",
    )


class GoalProb(BaseModel):
    goal: str
    prob: float


class PartnerBeliefOut(BaseModel):
    index: int
    top: list[GoalProb] = Field(description="the most probable goals, highest first")
    entropy: float = Field(description="of the belief, in nats (log G when uniform)")
    observed_action: int | None = Field(description="the action this step's update used")
    updates: int = Field(description="actions incorporated so far")


class SessionSettingsOut(BaseModel):
    env: str
    ego_goal: str
    partners: list[SessionPartnerIn]
    method: MethodName
    temperature: float | None
    regret_bound: float | None
    budget: float | None = None
    seed: int | None
    alias: str
    versions: dict[str, int]
    belief: BeliefIn


class SessionOut(BaseModel):
    session_id: str
    step: int = Field(description="the index the next step gets (steps taken so far)")
    expires_in_s: float = Field(description="idle time left before the session expires")
    beliefs: list[PartnerBeliefOut] = Field(description="one per inferred partner")
    settings: SessionSettingsOut


class SessionStepOut(ActResponse):
    session_id: str
    step: int = Field(description="0-based index of this step")
    beliefs: list[PartnerBeliefOut] = Field(description="one per inferred partner, after the step")
