"""Typed results of the SDK: frozen dataclasses, the same whichever transport answered.

| type            | what                                                                 |
|-----------------|----------------------------------------------------------------------|
| `Action`        | the blended action distribution for one observation                  |
| `ActionColumns` | a batch's answer as arrays, one per field (`act_batch_columns`)      |
| `Diagnostics`   | task entropy, task weight w_t (eq. 9), partner weights w_i (eq. 10)  |
| `PartnerWeight` | one partner's weight, by its index in the ego's observation layout   |
| `ModelUsed`     | a model the answer was computed with (name, version, sha256, role)   |
| `PartnerBelief` | the belief over an inferred partner's goal: top goals, entropy       |
| `SessionStep`   | an `Action` of a session step, with the step's index and session id  |
| `SessionInfo`   | a REST session: next step, beliefs, idle time left, settings         |
| `EnvInfo`       | an environment the server knows (goals, layout, action meanings)     |
| `Health`        | liveness and readiness of a server                                   |

`from_json` builds each from the REST API's JSON; the gRPC client builds them from protobuf
(`ActionColumns.from_sequences` from either).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass(frozen=True)
class PartnerWeight:
    index: int
    weight: float


@dataclass(frozen=True)
class Diagnostics:
    task_entropy: float
    task_weight: float
    partner_weights: tuple[PartnerWeight, ...] = ()

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Diagnostics:
        return cls(
            task_entropy=float(data["task_entropy"]),
            task_weight=float(data["task_weight"]),
            partner_weights=tuple(
                PartnerWeight(int(w["index"]), float(w["weight"]))
                for w in data.get("partner_weights", ())
            ),
        )


@dataclass(frozen=True)
class ModelUsed:
    role: str  # "task", "impact", "joint" or "monitor"
    name: str
    version: int
    sha256: str
    partner_index: int | None = None  # the partner an impact model stands for
    goal: str | None = None

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> ModelUsed:
        partner = data.get("partner_index")
        return cls(
            role=str(data["role"]),
            name=str(data["name"]),
            version=int(data["version"]),
            sha256=str(data["sha256"]),
            partner_index=None if partner is None else int(partner),
            goal=data.get("goal"),
        )


@dataclass(frozen=True)
class PartnerBelief:
    """The belief over an inferred partner's goal after a step (sessions and episodes)."""

    index: int
    top: tuple[tuple[str, float], ...]  # the most probable goals, highest first
    entropy: float  # nats (log G when uniform)
    observed_action: int | None = None  # the action this step's update used
    updates: int = 0  # actions incorporated so far

    @property
    def goal(self) -> str:
        """The most probable goal."""
        return self.top[0][0]

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> PartnerBelief:
        action = data.get("observed_action")
        return cls(
            index=int(data["index"]),
            top=tuple((str(g["goal"]), float(g["prob"])) for g in data.get("top", ())),
            entropy=float(data["entropy"]),
            observed_action=None if action is None else int(action),
            updates=int(data.get("updates", 0)),
        )


@dataclass(frozen=True)
class Budget:
    """aail_budget's episode state after a step: the task value given up so far, the episode's
    budget and the ego's task value at this step; pass it back with the next step
    (`act(..., budget_state=action.budget)`)."""

    spent: float
    total: float
    value: float

    @classmethod
    def from_json(cls, data: Mapping[str, Any] | None) -> Budget | None:
        if data is None:
            return None
        return cls(float(data["spent"]), float(data["total"]), float(data["value"]))


@dataclass(frozen=True)
class Action:
    """The server's answer for one observation."""

    probs: tuple[float, ...]  # one probability per action, summing to 1
    action: int  # sampled from `probs` (seeded by the request's seed)
    greedy_action: int  # argmax of `probs`
    action_meaning: str  # the environment's name of `action`
    method: str
    diagnostics: Diagnostics
    models: tuple[ModelUsed, ...] = ()
    beliefs: tuple[PartnerBelief, ...] = ()  # one per inferred partner (sessions, episodes)
    budget: Budget | None = None  # aail_budget only

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Action:
        return cls(**_action_fields(data))


def _action_fields(data: Mapping[str, Any]) -> dict[str, Any]:
    return {
        "probs": tuple(float(p) for p in data["probs"]),
        "action": int(data["action"]),
        "greedy_action": int(data["greedy_action"]),
        "action_meaning": str(data.get("action_meaning", "")),
        "method": str(data["method"]),
        "diagnostics": Diagnostics.from_json(data["diagnostics"]),
        "models": tuple(ModelUsed.from_json(m) for m in data.get("models", ())),
        "beliefs": tuple(PartnerBelief.from_json(b) for b in data.get("beliefs", ())),
        "budget": Budget.from_json(data.get("budget")),
    }


def _column(values: Sequence[float] | None) -> np.ndarray | None:
    """An optional per-row column (absent, or empty in protobuf: None)."""
    if values is None or len(values) == 0:
        return None
    return np.array(values, dtype=np.float64)


# The per-row fields of a columns answer: the same names in the REST JSON and in protobuf.
COLUMN_FIELDS = (
    "probs",
    "actions",
    "greedy_actions",
    "action_meanings",
    "task_entropies",
    "task_weights",
    "partner_indices",
    "partner_weights",
)


@dataclass(frozen=True, eq=False)  # eq=False: the fields are arrays
class ActionColumns:
    """A batch's answer as columns: B rows, A actions, P partners; row b of every field is
    observation b's answer (`to_actions()` gives the `Action`s `act_batch` returns)."""

    method: str
    models: tuple[ModelUsed, ...]  # every row was computed with these
    probs: np.ndarray  # (B, A) float64
    actions: np.ndarray  # (B,) int64, sampled from `probs` (seeded by the request's seed)
    greedy_actions: np.ndarray  # (B,) int64, arg max of `probs`
    action_meanings: tuple[str, ...]  # B: the environment's name of each sampled action
    task_entropies: np.ndarray  # (B,) float64
    task_weights: np.ndarray  # (B,) float64, w_t
    partner_indices: tuple[int, ...]  # P, in the request's partner order
    partner_weights: np.ndarray  # (B, P) float64, w_i in `partner_indices` order
    budget_spent: np.ndarray | None = None  # (B,) aail_budget's state per row, else None
    budget_total: np.ndarray | None = None
    budget_value: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.probs)

    @classmethod
    def from_sequences(
        cls,
        *,
        rows: int,
        method: str,
        models: Iterable[ModelUsed],
        probs: Sequence[Any],
        actions: Sequence[int],
        greedy_actions: Sequence[int],
        action_meanings: Iterable[str],
        task_entropies: Sequence[float],
        task_weights: Sequence[float],
        partner_indices: Iterable[int],
        partner_weights: Sequence[Any],
        budget_spent: Sequence[float] | None = None,
        budget_total: Sequence[float] | None = None,
        budget_value: Sequence[float] | None = None,
    ) -> ActionColumns:
        """From JSON lists (nested) or protobuf repeated fields (flat, row-major) of `rows` rows."""
        indices = tuple(int(i) for i in partner_indices)
        return cls(
            method=str(method),
            models=tuple(models),
            probs=np.array(probs, dtype=np.float64).reshape(rows, -1),
            actions=np.array(actions, dtype=np.int64),
            greedy_actions=np.array(greedy_actions, dtype=np.int64),
            action_meanings=tuple(str(m) for m in action_meanings),
            task_entropies=np.array(task_entropies, dtype=np.float64),
            task_weights=np.array(task_weights, dtype=np.float64),
            partner_indices=indices,
            partner_weights=np.array(partner_weights, dtype=np.float64).reshape(rows, len(indices)),
            budget_spent=_column(budget_spent),
            budget_total=_column(budget_total),
            budget_value=_column(budget_value),
        )

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> ActionColumns:
        """From the REST API's `"format": "columns"` answer."""
        return cls.from_sequences(
            rows=len(data["actions"]),
            method=data["method"],
            models=[ModelUsed.from_json(m) for m in data["models"]],
            budget_spent=data.get("budget_spent"),
            budget_total=data.get("budget_total"),
            budget_value=data.get("budget_value"),
            **{name: data[name] for name in COLUMN_FIELDS},
        )

    def to_actions(self) -> list[Action]:
        """One `Action` per row, as `act_batch` returns them."""
        probs, actions = self.probs.tolist(), self.actions.tolist()
        greedy, entropies = self.greedy_actions.tolist(), self.task_entropies.tolist()
        task_weights, partner_weights = self.task_weights.tolist(), self.partner_weights.tolist()
        budgets: list[Budget | None] = [None] * len(probs)
        if (
            self.budget_spent is not None
            and self.budget_total is not None
            and self.budget_value is not None
        ):
            budgets = [
                Budget(s, t, v)
                for s, t, v in zip(
                    self.budget_spent.tolist(),
                    self.budget_total.tolist(),
                    self.budget_value.tolist(),
                    strict=True,
                )
            ]
        return [
            Action(
                probs=tuple(probs[b]),
                action=actions[b],
                greedy_action=greedy[b],
                action_meaning=self.action_meanings[b],
                method=self.method,
                diagnostics=Diagnostics(
                    task_entropy=entropies[b],
                    task_weight=task_weights[b],
                    partner_weights=tuple(
                        PartnerWeight(index, weight)
                        for index, weight in zip(
                            self.partner_indices, partner_weights[b], strict=True
                        )
                    ),
                ),
                models=self.models,
                budget=budgets[b],
            )
            for b in range(len(probs))
        ]


@dataclass(frozen=True)
class SessionStep(Action):
    """The answer to a REST session step: the action, the beliefs, and which step it was."""

    session_id: str = ""
    step: int = 0  # 0-based index of this step

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> SessionStep:
        return cls(
            **_action_fields(data), session_id=str(data["session_id"]), step=int(data["step"])
        )


@dataclass(frozen=True)
class SessionInfo:
    """A REST session as `GET /v1/sessions/{id}` describes it."""

    session_id: str
    step: int  # the index the next step gets
    expires_in_s: float  # idle time left
    beliefs: tuple[PartnerBelief, ...] = ()
    settings: Mapping[str, Any] = field(default_factory=dict)  # the session's settings (JSON)

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> SessionInfo:
        return cls(
            session_id=str(data["session_id"]),
            step=int(data["step"]),
            expires_in_s=float(data["expires_in_s"]),
            beliefs=tuple(PartnerBelief.from_json(b) for b in data.get("beliefs", ())),
            settings=dict(data.get("settings", {})),
        )


@dataclass(frozen=True)
class EnvInfo:
    """An environment as `GET /v1/envs` / `ListEnvs` describes it."""

    name: str
    goals: tuple[str, ...]
    action_meanings: tuple[str, ...]
    max_agents: int
    obs_dims: Mapping[int, int] = field(default_factory=dict)  # agent count -> observation length
    observation_layouts: Mapping[int, tuple[str, ...]] = field(default_factory=dict)
    state_layout: tuple[str, ...] | None = None  # one agent's state row; None: no state input
    pair_obs_dim: int = 0
    methods: tuple[str, ...] = ()

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> EnvInfo:
        state_layout = data.get("state_layout")
        return cls(
            name=str(data["name"]),
            goals=tuple(data.get("goals", ())),
            action_meanings=tuple(data.get("action_meanings", ())),
            max_agents=int(data.get("max_agents", 0)),
            obs_dims={int(n): int(d) for n, d in data.get("obs_dims", {}).items()},
            observation_layouts={
                int(n): tuple(names) for n, names in data.get("observation_layouts", {}).items()
            },
            state_layout=None if state_layout is None else tuple(state_layout),
            pair_obs_dim=int(data.get("pair_obs_dim", 0)),
            methods=tuple(data.get("methods", ())),
        )


@dataclass(frozen=True)
class Health:
    live: bool  # the server answers
    ready: bool  # models loaded and store reachable
    detail: Mapping[str, Any] = field(default_factory=dict)
