"""Checks of a session's settings (once, at creation) and of each step's `observed` entries.
Every bad input becomes `InvalidRequest(field, message)` in the REST body's naming.

| field                        | rule                                                             |
|------------------------------|------------------------------------------------------------------|
| `env`, `ego_goal`, `method`, | as for `/v1/act` (`services.engine.validation`), checked on a    |
| `temperature`,               | stand-in observation of the smallest scene that holds every      |
| `regret_bound`, `seed`,      | partner; a pinned name must be a task or impact network of the   |
| `alias`, `versions`          | env (or, with jl, the joint network)                             |
| `partners[i].index`          | 1..max_agents-1 of the env, no index twice                       |
| `partners[i].goal(_probs)`   | at most one of the two; a known goal / a distribution summing to |
|                              | 1; with `infer` it is the belief's prior                         |
| `partners[i].infer`          | not with method jl (a joint network needs announced goals)       |
| `belief.forgetting`, `.floor`,| `policy.belief.BeliefConfig.validate`                           |
| `.temperature`, `.noise`,    |                                                                  |
| `.prune_below`, `.prune_error`|                                                                 |
| `belief.blend_mass`          | a number in (0, 1]                                               |
| `belief.blend_max_goals`     | null (no bound) or an integer >= 1                               |
| `observed`                   | none at step 0 (there is no previous observation to judge the    |
|                              | actions on)                                                      |
| `observed[j].index`          | an inferred partner, at most once per step                       |
| `observed[j].action`         | None (recover it) or an integer in 0..n_actions-1                |
"""

from __future__ import annotations

import contextlib
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from model_store.errors import InvalidArgument, brief
from model_store.naming import joint_model_name
from policy.belief import BeliefConfig, PreparedUpdate, initial_log_belief, prior_log_probs
from services.engine import ActRequest, InvalidRequest, PartnerSpec
from services.engine.environments import EnvRuntime, env_runtime
from services.engine.validation import CheckedPartner, check_partners, check_request
from services.sessions.messages import Observed, SessionPartner, SessionSettings


@dataclass(frozen=True, eq=False)  # eq=False: arrays
class CheckedSettings:
    settings: SessionSettings
    runtime: EnvRuntime
    goals: tuple[str, ...]  # the env's goal catalogue: the belief's column order
    inferred: tuple[int, ...]  # positions in `settings.partners` of the inferred partners
    log_prior_PG: np.ndarray  # one row per inferred partner
    initial_PG: np.ndarray  # the prior with the floor applied: the belief before any action
    update: PreparedUpdate  # `update_log_belief` with these priors and `settings.belief`
    inferred_indices: tuple[int, ...]  # the inferred partners' indices, in partner order
    # per partner: what `check_request` makes of it when announced (fixed), None when inferred
    announced: tuple[CheckedPartner | None, ...]
    # an unseeded session's `ActRequest` for `engine.act_checked`, the same at every step: the
    # engine reads neither its observations (a stand-in) nor its partners (the step's
    # `CheckedRequest` holds both)
    act_request: ActRequest


def _is_int(value: object) -> bool:
    return isinstance(value, int | np.integer) and not isinstance(value, bool)


def _split_field(err: ValueError, default: str) -> tuple[str, str]:
    """("belief.floor", "expected ...") from a ValueError written "belief.floor: expected ..."."""
    text = str(err)
    head, sep, rest = text.partition(": ")
    if sep and head and " " not in head:
        return head, rest
    return default, text


def _check_partner_indices(partners: object, runtime: EnvRuntime) -> tuple[SessionPartner, ...]:
    if not isinstance(partners, tuple | list):
        raise InvalidRequest("partners", "expected a list of partners")
    top = runtime.domain.max_agents - 1
    seen: set[int] = set()
    for i, partner in enumerate(partners):
        if not isinstance(partner, SessionPartner):
            raise InvalidRequest(f"partners[{i}]", "expected a SessionPartner")
        index = partner.index
        if not _is_int(index) or not 1 <= index <= top:
            expected = f"1..{top}" if top else "none (the env has a single agent)"
            raise InvalidRequest(
                f"partners[{i}].index",
                f"expected an integer in {expected} (env {runtime.domain.name!r} has at most "
                f"{runtime.domain.max_agents} agents), got {brief(index)}",
            )
        if index in seen:
            raise InvalidRequest(f"partners[{i}].index", f"partner index {index} given twice")
        seen.add(int(index))
        if not isinstance(partner.infer, bool):
            raise InvalidRequest(
                f"partners[{i}].infer", f"expected true or false, got {brief(partner.infer)}"
            )
    return tuple(partners)


def _dry_act_request(settings: SessionSettings, runtime: EnvRuntime) -> ActRequest:
    """The act request of a stand-in step: zeros for the smallest scene that holds every
    partner; an inferred partner without a prior stands in with the catalogue's first goal."""
    n_agents = max((p.index for p in settings.partners), default=0) + 1
    specs = tuple(
        PartnerSpec(
            p.index,
            runtime.domain.goals[0] if p.goal is None and p.goal_probs is None else p.goal,
            p.goal_probs,
        )
        for p in settings.partners
    )
    return ActRequest(
        env=settings.env,
        ego_goal=settings.ego_goal,
        observations=np.zeros((1, runtime.domain.obs_dim(n_agents))),
        partners=specs,
        method=settings.method,
        temperature=settings.temperature,
        regret_bound=settings.regret_bound,
        budget=settings.budget,
        seed=settings.seed,
        alias=settings.alias,
        versions=settings.versions,
    )


def _check_pins_usable(
    settings: SessionSettings, runtime: EnvRuntime, partners: Sequence[SessionPartner]
) -> None:
    """A pin must name a network the session could use: any task or impact network of the env
    (beliefs weigh every goal), or with jl its joint network."""
    usable = {*runtime.task_names.values(), *runtime.impact_names.values()}
    if settings.method == "jl":
        ordered = sorted(partners, key=lambda p: p.index)
        with contextlib.suppress(InvalidArgument, TypeError):  # the act check named it already
            goals = [p.goal for p in ordered if isinstance(p.goal, str)]
            usable.add(joint_model_name(runtime.domain.name, settings.ego_goal, goals))
    for name in settings.versions:
        if name not in usable:
            raise InvalidRequest(
                f"versions[{name}]",
                f"this session can use no model {name!r}: a pin must name a task or impact "
                f"network of env {runtime.domain.name!r} (or, with jl, its joint network)",
            )


def _check_blend(settings: SessionSettings) -> None:
    mass = settings.blend_mass
    if not isinstance(mass, int | float) or isinstance(mass, bool) or not 0 < mass <= 1:
        raise InvalidRequest("belief.blend_mass", f"expected a number in (0, 1], got {brief(mass)}")
    max_goals = settings.blend_max_goals
    if max_goals is not None and (not _is_int(max_goals) or max_goals < 1):
        raise InvalidRequest(
            "belief.blend_max_goals", f"expected null or an integer >= 1, got {brief(max_goals)}"
        )


def check_settings(settings: SessionSettings) -> CheckedSettings:
    """Check every field (module docstring) and build the inferred partners' priors."""
    if not isinstance(settings, SessionSettings):
        raise InvalidRequest(None, f"expected SessionSettings, got {type(settings).__name__}")
    runtime = env_runtime(settings.env)
    partners = _check_partner_indices(settings.partners, runtime)
    inferred = tuple(i for i, p in enumerate(partners) if p.inferred)
    if settings.method == "jl" and inferred:
        raise InvalidRequest(
            f"partners[{inferred[0]}].infer",
            "method jl needs every partner's announced goal (a joint network exists per goal "
            "combination); use aail or nail with inferred goals",
        )
    check_request(_dry_act_request(settings, runtime), max_batch=1)
    _check_pins_usable(settings, runtime, partners)
    goals = tuple(runtime.domain.goals)
    config = settings.belief
    if not isinstance(config, BeliefConfig):
        raise InvalidRequest("belief", f"expected a BeliefConfig, got {type(config).__name__}")
    try:
        config.validate(len(goals))
    except ValueError as err:
        raise InvalidRequest(*_split_field(err, "belief")) from None
    _check_blend(settings)
    priors = []
    for i in inferred:
        partner = partners[i]
        try:
            priors.append(prior_log_probs(goals, partner.goal_probs, announced=partner.goal))
        except ValueError as err:
            _, message = _split_field(err, "prior")
            suffix = "goal" if partner.goal is not None else "goal_probs"
            raise InvalidRequest(f"partners[{i}].{suffix}", message) from None
    log_prior_PG = np.asarray(priors, dtype=np.float64).reshape(len(inferred), len(goals))
    initial_PG = np.asarray(
        [initial_log_belief(row, config) for row in log_prior_PG], dtype=np.float64
    ).reshape(log_prior_PG.shape)
    announced = tuple(
        None
        if i in inferred
        else check_partners((PartnerSpec(p.index, p.goal, p.goal_probs),), runtime, p.index + 1)[0]
        for i, p in enumerate(partners)
    )
    act_request = replace(_dry_act_request(settings, runtime), partners=(), seed=None)
    return CheckedSettings(
        settings,
        runtime,
        goals,
        inferred,
        log_prior_PG,
        initial_PG,
        PreparedUpdate(log_prior_PG, config),
        tuple(partners[i].index for i in inferred),
        announced,
        act_request,
    )


def check_observed(
    observed: object, inferred_indices: Sequence[int], step: int, has_previous: bool, n_actions: int
) -> tuple[Observed, ...]:
    """The `observed` entries of step `step`, checked (module docstring)."""
    if not isinstance(observed, tuple | list):
        raise InvalidRequest("observed", "expected a list of {index, action} entries")
    if observed and not has_previous:
        raise InvalidRequest(
            "observed",
            f"step {step} has no previous observation: send the partners' actions from the next "
            "step on (each the action taken between the previous step's observation and this one)",
        )
    seen: set[int] = set()
    for j, entry in enumerate(observed):
        if not isinstance(entry, Observed):
            raise InvalidRequest(f"observed[{j}]", "expected an Observed entry")
        if not _is_int(entry.index) or entry.index not in inferred_indices:
            shown = ", ".join(map(str, inferred_indices)) or "none"
            raise InvalidRequest(
                f"observed[{j}].index",
                f"{brief(entry.index)} is not an inferred partner (inferred partners: {shown}); "
                "create the session with infer on that partner",
            )
        if entry.index in seen:
            raise InvalidRequest(f"observed[{j}].index", f"partner {entry.index} given twice")
        seen.add(int(entry.index))
        action = entry.action
        if action is not None and (not _is_int(action) or not 0 <= action < n_actions):
            raise InvalidRequest(
                f"observed[{j}].action",
                f"expected an action in 0..{n_actions - 1} (or none: recover it), got {brief(action)}",
            )
    return tuple(observed)
