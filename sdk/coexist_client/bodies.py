"""Request bodies shared by every SDK client: the REST API's JSON, which the gRPC clients translate.

Partners may be given as

| form                                   | meaning                                          |
|----------------------------------------|--------------------------------------------------|
| `{1: "b3"}`                            | partner at index 1 announced goal b3             |
| `{1: {"b3": 0.7, "c": 0.3}}`           | a distribution over partner 1's goals            |
| `[PartnerSpec(1, goal="b3"), ...]`     | objects with `index`, `goal`, `goal_probs`       |
| `[{"index": 1, "goal": "b3"}, ...]`    | the REST JSON form                               |
| `{1: None}`                            | sessions and episodes: infer partner 1's goal    |
|                                        | (uniform prior); `infer=[1]` with a goal above   |
|                                        | makes that goal the prior instead                |

A session step's `observed` (the partners' actions since the previous step) may be given as
`{1: 3}` (partner 1 took action 3; `None`: the server recovers it from the observations) or as a
list of `{"index": 1, "action": 3}` / objects with `index` and `action`.

Observations are checked here for shape and finiteness (JSON cannot carry NaN or inf); every
other check is the server's, so the SDK and the server cannot disagree about what is valid.
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any, TypedDict, TypeVar, Unpack

import numpy as np
from numpy.typing import ArrayLike

from coexist_client.errors import InvalidArgument
from coexist_client.types import Budget

# The values are `str | Mapping[str, float]`; typed `Any` so mixed dict literals type-check.
Partners = Mapping[int, Any] | Sequence[Any] | None


def _bad(field: str, message: str) -> InvalidArgument:
    return InvalidArgument("invalid_argument", f"{field}: {message}", field)


def _partner_from_object(item: Any, field: str) -> dict[str, Any]:
    if isinstance(item, Mapping):
        index, goal, goal_probs = item.get("index"), item.get("goal"), item.get("goal_probs")
    elif hasattr(item, "index"):
        index = item.index
        goal, goal_probs = getattr(item, "goal", None), getattr(item, "goal_probs", None)
    else:
        raise _bad(field, f"expected a partner spec (index, goal or goal_probs), got {item!r}")
    infer = item.get("infer") if isinstance(item, Mapping) else getattr(item, "infer", None)
    spec: dict[str, Any] = {"index": index}
    if goal is not None:
        spec["goal"] = goal
    if goal_probs is not None:
        spec["goal_probs"] = dict(goal_probs)
    if infer:
        spec["infer"] = True
    return spec


def normalise_partners(partners: Partners, *, infer_allowed: bool = False) -> list[dict[str, Any]]:
    """Partners in the REST JSON form, `[{"index": 1, "goal": "b3"}, ...]`; `{i: None}` (infer
    the goal) only with `infer_allowed` (sessions and episodes)."""
    if partners is None:
        return []
    if isinstance(partners, Mapping):
        specs = []
        for index, goal in partners.items():
            if isinstance(goal, str):
                specs.append({"index": index, "goal": goal})
            elif isinstance(goal, Mapping):
                specs.append({"index": index, "goal_probs": dict(goal)})
            elif goal is None and infer_allowed:  # nothing announced: the server infers it
                specs.append({"index": index, "infer": True})
            else:
                also = "" if infer_allowed else " (None, to infer the goal: sessions and episodes)"
                raise _bad(
                    f"partners[{index}]",
                    f"expected a goal or goal probabilities{also}, got {goal!r}",
                )
        return specs
    if isinstance(partners, str | bytes):
        raise _bad("partners", "expected a mapping or a list of partner specs, got a string")
    return [_partner_from_object(p, f"partners[{k}]") for k, p in enumerate(partners)]


def _finite_rows(values: Any, field: str, ndim: int) -> list[Any]:
    try:
        array = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        raise _bad(field, f"expected a {ndim}-D array of numbers") from None
    if array.ndim != ndim:
        raise _bad(field, f"expected a {ndim}-D array of numbers, got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        bad = np.argwhere(~np.isfinite(array))[0].tolist()
        where = "".join(f"[{i}]" for i in bad)
        raise _bad(f"{field}{where}", "expected a finite number (NaN and inf are refused)")
    rows: list[Any] = array.tolist()
    return rows


class Settings(TypedDict, total=False):
    """The policy settings that acts, batches and sessions take as keywords (`**settings`).
    Left out: no partners, method "aail_bounded", alias "production", the rest None (the
    server's temperature and regret bound, unseeded, the alias's versions)."""

    partners: Partners
    method: str
    temperature: float | None
    regret_bound: float | None
    budget: float | None
    seed: int | None
    alias: str
    versions: Mapping[str, int] | None


def policy_settings(
    env: str,
    ego_goal: str,
    *,
    partners: Partners = None,
    method: str = "aail_bounded",
    temperature: float | None = None,
    regret_bound: float | None = None,
    budget: float | None = None,
    seed: int | None = None,
    alias: str = "production",
    versions: Mapping[str, int] | None = None,
) -> dict[str, Any]:
    """The JSON fields of `Settings`, common to every body: the one place their defaults live
    and an unknown keyword is refused (TypeError); mypy checks `Settings` against it."""
    for name, value in (
        ("temperature", temperature),
        ("regret_bound", regret_bound),
        ("budget", budget),
    ):
        if value is not None and not math.isfinite(value):
            raise _bad(name, "expected a finite number")
    body = {
        "env": env,
        "ego_goal": ego_goal,
        "partners": normalise_partners(partners),
        "method": method,
        "temperature": temperature,
        "regret_bound": regret_bound,
        "seed": seed,
        "alias": alias,
        "versions": dict(versions or {}),
    }
    if budget is not None:  # aail_budget only (a server refuses it with any other method)
        body["budget"] = budget
    return body


F = TypeVar("F", bound=Callable[..., Any])


def shows_settings(function: F) -> F:
    """`function` (one taking `**settings: Unpack[Settings]` last) signed with those keywords
    spelled out, defaults included, so help(), IDEs and `inspect.signature` show them all."""
    signature = inspect.signature(function)
    *own, settings = signature.parameters.values()
    assert settings.kind is settings.VAR_KEYWORD, function
    keywords = inspect.signature(policy_settings).parameters.values()
    shared = [p for p in keywords if p.kind is p.KEYWORD_ONLY]
    function.__signature__ = signature.replace(  # type: ignore[attr-defined]
        parameters=[*own, *shared]
    )
    return function


@shows_settings
def act_body(
    env: str,
    ego_goal: str,
    observation: ArrayLike | None = None,
    *,
    state: ArrayLike | None = None,
    ego_index: int = 0,
    budget_state: Budget | None = None,
    **settings: Unpack[Settings],
) -> dict[str, Any]:
    """The JSON body of `POST /v1/act`; `budget_state`: aail_budget's `Action.budget` of the
    episode's last step (None at its first)."""
    body = policy_settings(env, ego_goal, **settings)
    body.update(observation_fields(observation, state, ego_index))
    if budget_state is not None:
        body["budget_spent"], body["budget_total"] = budget_state.spent, budget_state.total
        body["budget_value"] = budget_state.value
    return body


def observation_fields(
    observation: Any, state: Any, ego_index: int, *, batch: bool = False
) -> dict[str, Any]:
    """`{"observation": [...]}` or `{"state": [[...], ...], "ego_index": i}` (exactly one given);
    with `batch`, `observations` or `states` (+ `ego_index`), one rank more."""
    field, state_field = ("observations", "states") if batch else ("observation", "state")
    rank = 2 if batch else 1
    if (observation is None) == (state is None):
        raise _bad(field, f"give exactly one of {field} and {state_field} (+ ego_index)")
    if observation is not None:
        return {field: _finite_rows(observation, field, rank)}
    return {state_field: _finite_rows(state, state_field, rank + 1), "ego_index": ego_index}


@shows_settings
def act_batch_body(
    env: str,
    ego_goal: str,
    observations: ArrayLike | None = None,
    *,
    states: ArrayLike | None = None,
    ego_index: int = 0,
    budget_spent: ArrayLike | None = None,
    budget_total: ArrayLike | None = None,
    budget_value: ArrayLike | None = None,
    **settings: Unpack[Settings],
) -> dict[str, Any]:
    """The JSON body of `POST /v1/act:batch` (rows; `columns_exchange` asks for columns);
    `budget_spent`, `budget_total` and `budget_value`: aail_budget's state per row from the last
    answer."""
    body = policy_settings(env, ego_goal, **settings)
    body.update(observation_fields(observations, states, ego_index, batch=True))
    carried = {"budget_spent": budget_spent, "budget_total": budget_total}
    carried["budget_value"] = budget_value
    for field, values in carried.items():
        if values is not None:
            body[field] = _finite_rows(values, field, 1)
    return body


def _inferring(partners: Partners, infer: Sequence[int]) -> list[dict[str, Any]]:
    """Partners in JSON form with `infer` set on the indices in `infer` (added if absent)."""
    specs = normalise_partners(partners, infer_allowed=True)
    wanted = list(infer)
    for spec in specs:
        if spec["index"] in wanted:
            spec["infer"] = True
    known = {spec["index"] for spec in specs}
    specs += [{"index": i, "infer": True} for i in wanted if i not in known]
    return specs


@shows_settings
def session_body(
    env: str,
    ego_goal: str,
    *,
    infer: Sequence[int] = (),
    belief: Mapping[str, Any] | None = None,
    **settings: Unpack[Settings],
) -> dict[str, Any]:
    """The JSON body of `POST /v1/sessions` (also an Episode's settings): `act_body`'s
    fields without the observation, `infer` marked on partners (who may be `{i: None}`), plus
    `belief` (forgetting, floor, temperature, noise, blend_mass, blend_max_goals, prune_below,
    prune_error; left out: the server's defaults)."""
    partners = settings.pop("partners", None)
    body = policy_settings(env, ego_goal, **settings)
    body["partners"] = _inferring(partners, infer)
    if belief is not None:
        if not isinstance(belief, Mapping):
            raise _bad("belief", f"expected a mapping (forgetting, floor, ...), got {belief!r}")
        body["belief"] = {k: v for k, v in belief.items() if v is not None}
    return body


Observed = Mapping[int, Any] | Sequence[Any] | None


def observed_entries(observed: Observed) -> list[dict[str, Any]]:
    """`observed` in the REST JSON form, `[{"index": 1, "action": 3}, ...]` (module docstring)."""
    if observed is None:
        return []
    if isinstance(observed, Mapping):
        items = [{"index": index, "action": action} for index, action in observed.items()]
    elif isinstance(observed, str | bytes):
        raise _bad("observed", "expected a mapping of partner index to action, or a list")
    else:
        items = []
        for j, entry in enumerate(observed):
            if isinstance(entry, Mapping):
                items.append({"index": entry.get("index"), "action": entry.get("action")})
            elif hasattr(entry, "index"):
                items.append({"index": entry.index, "action": getattr(entry, "action", None)})
            else:
                raise _bad(f"observed[{j}]", f"expected {{index, action}}, got {entry!r}")
    return [{k: v for k, v in item.items() if v is not None} for item in items]


def step_body(
    observation: Any = None,
    *,
    state: Any = None,
    ego_index: int = 0,
    observed: Observed = None,
    expected_step: int | None = None,
) -> dict[str, Any]:
    """The JSON body of `POST /v1/sessions/{id}/steps`."""
    body = observation_fields(observation, state, ego_index)
    body["observed"] = observed_entries(observed)
    if expected_step is not None:
        body["expected_step"] = expected_step
    return body


def step_seed(seed: int | None, step: int) -> int | None:
    """The seed of step `step` of an episode: seed + step (the `Episode` stream's rule)."""
    return None if seed is None else seed + step
