"""What goes into and comes out of a session: plain frozen dataclasses (the issue-9 contract).

| class               | what                                                                   |
|---------------------|------------------------------------------------------------------------|
| `SessionPartner`    | one partner: its index, an announced goal / goal distribution, and     |
|                     | whether the server infers its goal (then the given goal is the prior)  |
| `SessionSettings`   | what `POST /v1/act` takes minus the observation, plus the belief's     |
|                     | settings (`policy.belief.BeliefConfig`) and how the belief is blended  |
| `Observed`          | what the client saw a partner do since the previous step               |
| `PartnerBelief`     | one inferred partner's belief: top goals, entropy, update counters     |
| `SessionStepResult` | one step's answer: the engine's `ActResult` plus the beliefs           |
| `SessionInfo`       | a session as `GET /v1/sessions/{id}` describes it                      |
| `SessionState`      | what a session carries from one step to the next (`Session.export_state`)|
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from policy.belief import BeliefConfig
from services.engine import ActResult, Method
from services.engine.messages import DEFAULT_ALIAS, DEFAULT_METHOD

TOP_GOALS = 3  # goals listed per partner belief


@dataclass(frozen=True)
class SessionPartner:
    index: int  # the partner's position in the ego's observation layout (1..N-1)
    goal: str | None = None  # announced goal (without infer: fixed, as in /v1/act)
    goal_probs: Mapping[str, float] | None = None  # or a distribution over goals
    # True: keep a belief from observed actions; a given goal / goal_probs is then its prior.
    # Neither goal nor goal_probs: inference is implied, from a uniform prior.
    infer: bool = False

    @property
    def inferred(self) -> bool:
        return self.infer or (self.goal is None and self.goal_probs is None)


@dataclass(frozen=True)
class SessionSettings:
    env: str
    ego_goal: str
    partners: tuple[SessionPartner, ...] = ()
    method: Method = DEFAULT_METHOD
    temperature: float | None = None  # of the act pass (default: the task model's training α)
    regret_bound: float | None = None  # aail_bounded's ε (default: twice the task model's α)
    budget: float | None = None  # aail_budget's budget B (`policy.regret_budget`)
    seed: int | None = None  # step t samples with seed + t
    alias: str = DEFAULT_ALIAS
    versions: Mapping[str, int] = field(default_factory=dict)
    belief: BeliefConfig = field(default_factory=BeliefConfig)
    # The act pass blends each inferred partner's impact networks by its belief
    # (`policy.belief.blend_goal_probs`). Default: every goal, the exact expected impact Q and
    # the same networks at every step. A smaller mass or a goal bound keeps only the top goals:
    # fewer networks, but each new set of them costs the engine a new stacked group.
    blend_mass: float = 1.0  # the belief mass whose most probable goals are blended, (0, 1]
    blend_max_goals: int | None = None  # at most this many goals per partner (None: no bound)

    @property
    def inferred_indices(self) -> tuple[int, ...]:
        return tuple(p.index for p in self.partners if p.inferred)


@dataclass(frozen=True)
class Observed:
    index: int  # the partner's index
    action: int | None = None  # None: recover it from the previous and current observations


@dataclass(frozen=True)
class PartnerBelief:
    index: int
    top: tuple[tuple[str, float], ...]  # the TOP_GOALS most probable goals, highest first
    entropy: float  # nats
    observed_action: int | None  # the action this step's update used (None: no update)
    updates: int  # actions incorporated so far


@dataclass(frozen=True)
class SessionStepResult:
    session_id: str
    step: int  # 0-based index of this step
    result: ActResult  # the blended action
    beliefs: tuple[PartnerBelief, ...]  # one per inferred partner, in partner order


@dataclass(frozen=True)
class SessionInfo:
    session_id: str
    settings: SessionSettings
    step: int  # the index the next step gets (= steps taken so far)
    beliefs: tuple[PartnerBelief, ...]
    expires_in_s: float  # idle time left before the session expires


@dataclass(frozen=True, eq=False)  # eq=False: arrays
class SessionState:
    """A session's state between two steps, without its settings (`Session.export_state`).
    There is no random state to carry: a seeded session samples step t with seed + t."""

    first_step: int
    next_step: int  # the index the next step gets
    log_belief_PG: np.ndarray  # float64 (inferred partners, goals)
    updates: tuple[int, ...]  # actions incorporated, per inferred partner
    last_actions: tuple[int | None, ...]  # the action the last update used, per inferred partner
    previous: np.ndarray | None  # float32 (1, D): the last step's observation
    previous_agents: int  # the agents `previous` holds
    # aail_budget's (spent S, budget B, the ego's task value V) after the last step
    budget: tuple[float, float, float] | None
    table_partners: tuple[int, ...]  # whose actions the next step likely brings (scoring ahead)
