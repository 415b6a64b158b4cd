"""Checks of an `ActRequest`: every bad input becomes `InvalidRequest(field, message)`.

| field                     | rule                                                                |
|---------------------------|---------------------------------------------------------------------|
| `env`                     | a registered environment                                            |
| `ego_goal`                | a goal of that environment                                          |
| `observations`            | shape (B, D), 1 <= B <= max_batch, D = domain.obs_dim(N) for some   |
|                           | N in 1..max_agents (N is inferred from D)                           |
| `observations[b]`         | finite, and finite in float32 (the networks' precision)             |
| `partners[i].index`       | an integer in 1..N-1, no index twice                                |
| `partners[i].goal`        | exactly one of `goal` and `goal_probs`; a goal of the env           |
| `partners[i].goal_probs`  | known goals, finite probabilities >= 0 summing to 1 (within 1e-6)   |
| `method`                  | one of aail, nail, sl, jl; jl needs >= 1 partner, each with a `goal`|
| `temperature`             | None or a finite number > 0                                         |
| `regret_bound`            | aail_bounded only; None or a finite number >= 0                     |
| `budget`                  | aail_budget only; None or a finite number >= 0                      |
| `budget_spent`,           | aail_budget only; all three None (the episode's first step) or all  |
| `budget_total`,           | three B finite numbers, one per observation row (spent and total    |
| `budget_value`            | >= 0; the value any sign)                                           |
| `seed`                    | None or an integer >= 0                                             |
| `alias`, `versions[name]` | a valid alias; pinned names are model names, their versions        |
|                           | integers in 1..MAX_VERSION; `engine.act` then refuses a pin of a    |
|                           | model the request does not use                                      |
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import cast

import numpy as np

from model_store.errors import InvalidArgument, brief
from model_store.naming import MAX_VERSION, validate_alias, validate_model_name
from services.engine.environments import EnvRuntime, env_runtime
from services.engine.errors import InvalidRequest
from services.engine.messages import METHODS, ActRequest, PartnerSpec

PROB_SUM_TOL = 1e-6
FLOAT32_MAX = float(np.finfo(np.float32).max)


@dataclass(frozen=True)
class CheckedPartner:
    index: int  # position in the ego's observation layout
    goals: tuple[str, ...]  # the goals with probability > 0 (one when announced)
    probs: tuple[float, ...] | None  # their probabilities; None for an announced goal


@dataclass(frozen=True)
class CheckedRequest:
    runtime: EnvRuntime
    obs_BD: np.ndarray  # float32
    n_agents: int
    partners: tuple[CheckedPartner, ...]
    # aail_budget's carried episode state, (B,) float64 each, or None at the first step
    budget_spent_B: np.ndarray | None = None
    budget_total_B: np.ndarray | None = None
    budget_value_B: np.ndarray | None = None

    @property
    def partners_key(self) -> tuple[tuple[int, tuple[str, ...], bool], ...]:
        """Per partner (index, goals, announced): what the partners fix of a request's networks
        and layout (the engine's look-ups by request shape), built on first use. Not a
        functools.cached_property: Python 3.11's computes under one lock shared by every
        instance, and every request (from any thread) makes a new instance."""
        key = self.__dict__.get("_partners_key")
        if key is None:
            key = tuple([(p.index, p.goals, p.probs is None) for p in self.partners])
            object.__setattr__(self, "_partners_key", key)  # frozen: set once, as a cache
        return key


def _is_int(value: object) -> bool:
    if type(value) is int:  # the common case first: one type check
        return True
    return isinstance(value, int | np.integer) and not isinstance(value, bool)


def _is_real(value: object) -> bool:
    if type(value) is float or type(value) is int:
        return True
    return isinstance(value, int | float | np.integer | np.floating) and not isinstance(value, bool)


def _known_goal(goal: object, runtime: EnvRuntime) -> bool:
    return isinstance(goal, str) and goal in runtime.goals


def check_observations(obs: object, runtime: EnvRuntime, max_batch: int) -> tuple[np.ndarray, int]:
    """The observations as float32 (B, D) and the number of agents N they describe."""
    if not isinstance(obs, np.ndarray) or obs.dtype.kind not in "fiu":
        try:
            obs = np.asarray(obs, dtype=np.float64)
        except (TypeError, ValueError):
            raise InvalidRequest(
                "observations", "expected a (B, obs_dim) array of numbers"
            ) from None
    assert isinstance(obs, np.ndarray)
    if obs.ndim != 2:
        raise InvalidRequest("observations", f"expected shape (B, obs_dim), got {obs.shape}")
    batch, dim = obs.shape
    if batch == 0:
        raise InvalidRequest("observations", "empty batch: expected at least one observation")
    if batch > max_batch:
        raise InvalidRequest("observations", f"batch of {batch} exceeds the maximum {max_batch}")
    n_agents = runtime.agents_by_obs_dim.get(dim)
    if n_agents is None:
        allowed = ", ".join(
            f"{d} ({n} agent{'s' if n > 1 else ''})" for d, n in runtime.agents_by_obs_dim.items()
        )
        field = "observations[0]" if batch == 1 else "observations"
        raise InvalidRequest(field, f"length {dim} fits no agent count; expected one of {allowed}")
    if obs.dtype.kind == "f" and obs.dtype.itemsize > 4:  # may overflow float32: inf, no warning
        if np.maximum.reduce(np.abs(obs), axis=None) <= FLOAT32_MAX:  # NaN is not <=
            # every value within float32's range: a finite cast with nothing to silence (the
            # usual request, with two numpy calls fewer than the check below)
            return obs.astype(np.float32), n_agents
        with np.errstate(over="ignore"):
            obs32 = obs.astype(np.float32)
    else:  # float32 and narrower, integers: always in float32's range (no errstate needed)
        obs32 = obs.astype(np.float32)
    if not np.isfinite(obs32).all():
        row = int(np.argmin(np.isfinite(obs32).all(axis=1)))
        what = "NaN or inf" if not np.isfinite(obs[row]).all() else "values beyond float32 range"
        raise InvalidRequest(f"observations[{row}]", f"holds {what}")
    return obs32, n_agents


def _check_goal_probs(
    probs: object, runtime: EnvRuntime, field: str
) -> tuple[tuple[str, ...], tuple[float, ...]]:
    """The goals with probability > 0 and their probabilities (renormalised to sum to 1)."""
    if not isinstance(probs, Mapping) or not probs:
        raise InvalidRequest(field, "expected a non-empty mapping of goal to probability")
    checked = _clean_goal_probs(probs, runtime)
    if checked is not None:
        return checked
    goals, values = [], []
    for goal, p in probs.items():
        if not _known_goal(goal, runtime):
            raise InvalidRequest(
                field, f"unknown goal {brief(goal)} for env {runtime.domain.name!r}"
            )
        if not _is_real(p) or not math.isfinite(p) or p < 0:
            raise InvalidRequest(
                field, f"probability of {goal!r} must be finite and >= 0, got {brief(p)}"
            )
        goals.append(goal)
        values.append(float(p))
    try:
        total = math.fsum(values)
    except OverflowError:  # finite values whose sum is beyond float range: far from 1
        total = math.inf
    if abs(total - 1.0) > PROB_SUM_TOL:
        raise InvalidRequest(
            field, f"probabilities sum to {total:.9g}, expected 1 (±{PROB_SUM_TOL:g})"
        )
    # renormalised exactly, so that a sum just inside the tolerance stays inside it downstream
    kept = [(g, p / total) for g, p in zip(goals, values, strict=True) if p > 0]
    return tuple(g for g, _ in kept), tuple(p for _, p in kept)


def _clean_goal_probs(
    probs: Mapping[object, object], runtime: EnvRuntime
) -> tuple[tuple[str, ...], tuple[float, ...]] | None:
    """`_check_goal_probs`' answer for the usual mapping (known goals, float probabilities,
    all > 0, a finite sum within the tolerance) with a few whole-collection checks instead of
    one Python step per goal (a session's 35-goal belief on every step); None for anything else,
    which the per-goal loop then checks and names. The same numbers: a sum by `math.fsum` and a
    division by it."""
    values = cast(list[float], list(probs.values()))  # checked on the next line
    if not all(type(p) is float for p in values) or not runtime.goals.issuperset(probs):
        return None
    try:
        total = math.fsum(values)
    except (OverflowError, ValueError):  # inf - inf, or an overflow: not a distribution
        return None
    if not (min(values) > 0 and abs(total - 1.0) <= PROB_SUM_TOL):  # NaN fails both ways
        return None
    goals = cast(tuple[str, ...], tuple(probs))  # known goals: strings
    return goals, tuple([p / total for p in values])


def check_partner_index(index: int, n_agents: int, field: str) -> None:
    """A partner index must be one of the observation's other agents: 1..n_agents-1."""
    if not 1 <= index <= n_agents - 1:
        holds = f"the observation holds {n_agents} agent(s)"
        expected = f"1..{n_agents - 1}" if n_agents > 1 else "no partner index (only the ego)"
        raise InvalidRequest(field, f"{brief(index)} out of range: {holds}, expected {expected}")


def check_partners(
    partners: object, runtime: EnvRuntime, n_agents: int
) -> tuple[CheckedPartner, ...]:
    if not isinstance(partners, tuple | list):
        raise InvalidRequest("partners", "expected a list of partners")
    checked: list[CheckedPartner] = []
    seen: set[int] = set()
    for i, partner in enumerate(partners):
        if not isinstance(partner, PartnerSpec):
            raise InvalidRequest(f"partners[{i}]", "expected a PartnerSpec")
        index = partner.index
        if not _is_int(index):
            raise InvalidRequest(f"partners[{i}].index", f"expected an integer, got {brief(index)}")
        check_partner_index(index, n_agents, f"partners[{i}].index")
        if index in seen:
            raise InvalidRequest(f"partners[{i}].index", f"partner index {index} given twice")
        seen.add(int(index))
        goal = partner.goal
        if (goal is None) == (partner.goal_probs is None):
            raise InvalidRequest(f"partners[{i}].goal", "give exactly one of goal and goal_probs")
        if goal is not None:
            if not _known_goal(goal, runtime):
                raise InvalidRequest(
                    f"partners[{i}].goal",
                    f"unknown goal {brief(goal)} for env {runtime.domain.name!r}",
                )
            checked.append(CheckedPartner(int(index), (goal,), None))
        else:
            field = f"partners[{i}].goal_probs"
            goals, probs = _check_goal_probs(partner.goal_probs, runtime, field)
            checked.append(CheckedPartner(int(index), goals, probs))
    return tuple(checked)


def check_request(request: ActRequest, max_batch: int) -> CheckedRequest:
    """Check every field of `request` (see the module docstring); raise `InvalidRequest`."""
    if not isinstance(request, ActRequest):
        raise InvalidRequest(None, f"expected an ActRequest, got {type(request).__name__}")
    runtime = env_runtime(request.env)
    if not _known_goal(request.ego_goal, runtime):
        raise InvalidRequest(
            "ego_goal", f"unknown goal {brief(request.ego_goal)} for env {runtime.domain.name!r}"
        )
    if not isinstance(request.method, str) or request.method not in METHODS:
        raise InvalidRequest(
            "method", f"unknown method {brief(request.method)}, expected one of {METHODS}"
        )
    obs_BD, n_agents = check_observations(request.observations, runtime, max_batch)
    partners = _remembered_partners(request.partners, runtime, n_agents)
    if request.method == "jl":
        if not partners:
            raise InvalidRequest("partners", "method jl needs at least one partner")
        for i, partner in enumerate(partners):
            if partner.probs is not None:
                raise InvalidRequest(
                    f"partners[{i}].goal_probs",
                    "method jl needs an announced goal (a joint network exists per goal combination)",
                )
    temperature = request.temperature
    if temperature is not None and (
        not _is_real(temperature) or not math.isfinite(temperature) or temperature <= 0
    ):
        raise InvalidRequest(
            "temperature", f"expected a finite number > 0, got {brief(temperature)}"
        )
    regret_bound = request.regret_bound
    if regret_bound is not None:
        if request.method != "aail_bounded":
            raise InvalidRequest(
                "regret_bound", f"applies to method aail_bounded only, not {brief(request.method)}"
            )
        if not _is_real(regret_bound) or not math.isfinite(regret_bound) or regret_bound < 0:
            raise InvalidRequest(
                "regret_bound", f"expected a finite number >= 0, got {brief(regret_bound)}"
            )
    spent_B, total_B, value_B = check_budget(request, obs_BD.shape[0])
    seed = request.seed
    if seed is not None and (not _is_int(seed) or seed < 0):
        raise InvalidRequest("seed", f"expected an integer >= 0, got {brief(seed)}")
    check_alias(request.alias)
    check_versions(request.versions)
    return CheckedRequest(runtime, obs_BD, n_agents, partners, spent_B, total_B, value_B)


def check_budget(
    request: ActRequest, n_rows: int
) -> tuple[np.ndarray | None, np.ndarray | None, np.ndarray | None]:
    """aail_budget's `budget`, `budget_spent`, `budget_total` and `budget_value` (module
    docstring): the carried state as (B,) float64 arrays, all None at an episode's first step."""
    carried = {
        "budget_spent": request.budget_spent,
        "budget_total": request.budget_total,
        "budget_value": request.budget_value,
    }
    if request.method != "aail_budget":
        for name, value in {"budget": request.budget, **carried}.items():
            if value is not None:
                raise InvalidRequest(
                    name, f"applies to method aail_budget only, not {brief(request.method)}"
                )
        return None, None, None
    budget = request.budget
    if budget is not None and (not _is_real(budget) or not math.isfinite(budget) or budget < 0):
        raise InvalidRequest("budget", f"expected a finite number >= 0, got {brief(budget)}")
    given = [name for name, value in carried.items() if value is not None]
    if not given:
        return None, None, None
    if len(given) < len(carried):
        missing = next(name for name in carried if name not in given)
        raise InvalidRequest(
            missing,
            "give budget_spent, budget_total and budget_value together (all from the episode's "
            "last answer), or none of them at the episode's first step",
        )
    spent_B = _budget_column(request.budget_spent, "budget_spent", n_rows)
    total_B = _budget_column(request.budget_total, "budget_total", n_rows)
    value_B = _budget_column(request.budget_value, "budget_value", n_rows, signed=True)
    return spent_B, total_B, value_B


def _budget_column(values: object, field: str, n_rows: int, signed: bool = False) -> np.ndarray:
    """One finite number per row (>= 0 unless `signed`), (B,) float64 (a scalar for one row is
    accepted)."""
    wanted = "numbers" if signed else "numbers >= 0"
    if _is_real(values):
        values = [values]
    if not isinstance(values, list | tuple | np.ndarray):
        raise InvalidRequest(field, f"expected one of the {wanted} per row, got {brief(values)}")
    try:
        array = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidRequest(field, f"expected {wanted}, got {brief(values)}") from None
    if array.shape != (n_rows,):
        raise InvalidRequest(
            field, f"expected {n_rows} number(s), one per observation row, got shape {array.shape}"
        )
    if not np.isfinite(array).all() or (not signed and (array < 0).any()):
        raise InvalidRequest(field, f"expected finite {wanted}, got {brief(values)}")
    return array


# Checked partners are kept, so that a client sending the same partners on every call has them
# checked once: by the tuple's identity where a transport passes the same tuple each time
# (`services.grpc_api.repeated`; the entry holds the tuple, so the id cannot be reused while the
# entry lives), and by their content where that is plain ints and goal names (a REST body makes
# new PartnerSpecs on every call). Only announced goals are kept: a goal_probs mapping could be
# edited between calls (so could a list, hence tuples only by identity).
_CHECKED_PARTNERS: dict[tuple[object, ...], tuple[object, tuple[CheckedPartner, ...]]] = {}
PARTNERS_MEMO_MAX = 256


def _content_key(partners: object) -> tuple[tuple[int, str], ...] | None:
    """(index, goal) per partner when each is a PartnerSpec with an `int` index and an announced
    `str` goal (then nothing else decides its check), else None."""
    if type(partners) is not tuple:
        return None
    key = []
    for partner in partners:
        if (
            type(partner) is not PartnerSpec
            or type(partner.index) is not int  # exactly int: True == 1 would share a key
            or type(partner.goal) is not str
            or partner.goal_probs is not None
        ):
            return None
        key.append((partner.index, partner.goal))
    return tuple(key)


def _remember(key: tuple[object, ...], entry: tuple[object, tuple[CheckedPartner, ...]]) -> None:
    if len(_CHECKED_PARTNERS) >= PARTNERS_MEMO_MAX:
        _CHECKED_PARTNERS.clear()
    _CHECKED_PARTNERS[key] = entry


def _remembered_partners(
    partners: object, runtime: EnvRuntime, n_agents: int
) -> tuple[CheckedPartner, ...]:
    env = runtime.domain.name
    by_identity = (id(partners), env, n_agents)
    hit = _CHECKED_PARTNERS.get(by_identity)
    if hit is not None and hit[0] is partners:
        return hit[1]
    passed_tuple = type(partners) is tuple
    if type(partners) is list:  # one snapshot for the key and the check alike
        partners = tuple(partners)
    content = _content_key(partners)
    by_content = None if content is None else (content, env, n_agents)
    if by_content is not None:
        hit = _CHECKED_PARTNERS.get(by_content)
        if hit is not None:
            return hit[1]
    checked = check_partners(partners, runtime, n_agents)
    if by_content is not None:
        _remember(by_content, (None, checked))
    if passed_tuple and all(c.probs is None for c in checked):
        _remember(by_identity, (partners, checked))
    return checked


_GOOD_ALIASES: set[str] = set()


def check_alias(alias: object) -> None:
    if isinstance(alias, str) and alias in _GOOD_ALIASES:
        return
    try:
        validate_alias(alias)  # type: ignore[arg-type]
    except InvalidArgument as exc:
        raise InvalidRequest("alias", str(exc).removeprefix("alias: ")) from None
    if len(_GOOD_ALIASES) < 1024:
        _GOOD_ALIASES.add(alias)  # type: ignore[arg-type]


def check_versions(versions: object) -> None:
    if not isinstance(versions, Mapping):
        raise InvalidRequest("versions", "expected a mapping of model name to version")
    for name, version in versions.items():
        if not isinstance(name, str):
            raise InvalidRequest("versions", f"model names must be strings, got {brief(name)}")
        try:
            validate_model_name(name, "versions")
        except InvalidArgument as exc:
            raise InvalidRequest("versions", str(exc).removeprefix("versions: ")) from None
        if not _is_int(version) or not 1 <= version <= MAX_VERSION:
            raise InvalidRequest(
                f"versions[{name}]",
                f"expected an integer >= 1 and <= {MAX_VERSION}, got {brief(version)}",
            )
