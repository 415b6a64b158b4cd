"""Server-side translation between protobuf messages and the engine's dataclasses.

| function                 | from                                  | to                            |
|--------------------------|---------------------------------------|-------------------------------|
| `act_request`            | `ActRequest`                          | engine `ActRequest` (B = 1)   |
| `batch_source`           | `ActBatchRequest`                     | which input form it uses      |
| `act_batch_request`      | `ActBatchRequest`                     | engine `ActRequest` (B rows)  |
| `episode_request`        | `EpisodeSettings` + `EpisodeStep`, t  | engine `ActRequest`, seed + t |
| `act_response`           | engine `ActResult`                    | `ActResponse`                 |
| `act_batch_response`     | engine `ActResult`s                   | `ActBatchResponse`            |
| `act_columns_response`   | engine `ActColumns`                   | `ActBatchResponse.columns`    |
| `infers_goals`           | `EpisodeSettings`                     | whether a partner is inferred |
| `session_settings`       | `EpisodeSettings`                     | `SessionSettings` (sessions)  |
| `session_step_inputs`    | `EpisodeStep`                         | observation (1, D), observed  |
| `session_response`       | `SessionStepResult`                   | `ActResponse` with `beliefs`  |
| `env_info`               | engine `EnvInfo`                      | `EnvInfo`                     |
| `renamed_for_transport`  | an `EngineError`                      | the same, blaming the field   |
| `renamed_for_batch`      |                                       | the client actually sent      |

Field names follow the REST API: a single request's rows are `observation` / `state` (the engine
calls them `observations[0]`), a batch of states is `states[b]`, a row of a batch's
`observation_matrix` is `observation_matrix[b]`. A matrix and the columns are read into and
filled from numpy in one call each (`np.array(values)`, `extend(ndarray)`), not one `Vector`
message per row. Unset proto3 fields take the REST defaults: method "aail_bounded", alias
"production", no temperature, no seed; an unset belief field the `SessionSettings` /
`BeliefConfig` default. `infer` is refused outside an Episode (a unary call
has no history of the partner's actions).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from itertools import chain
from typing import Any

import numpy as np

from policy.belief import BeliefConfig
from services.engine import (
    ActColumns,
    ActRequest,
    ActResult,
    EngineError,
    EnvInfo,
    InvalidRequest,
    ModelUsed,
    PartnerSpec,
    observations_from_states,
)
from services.engine.environments import env_runtime
from services.engine.messages import DEFAULT_ALIAS, DEFAULT_METHOD
from services.grpc_api import repeated
from services.grpc_api.gen.coexist.v1 import policy_pb2 as pb
from services.sessions import Observed, SessionPartner, SessionSettings, SessionStepResult

Settings = pb.ActRequest | pb.ActBatchRequest | pb.EpisodeSettings
Row = pb.ActRequest | pb.EpisodeStep  # messages carrying one observation (or state)
_NO_ROWS = np.empty((0, 0))  # a settings template's observations (`repeated.request_with`)


def _partners(specs: Sequence[pb.PartnerSpec]) -> tuple[PartnerSpec, ...]:
    for i, spec in enumerate(specs):
        if spec.infer:
            raise InvalidRequest(
                f"partners[{i}].infer",
                "goals are inferred in an Episode stream (or a REST session), which sees the "
                "partner's actions over time; a single call cannot",
            )
    return tuple(
        PartnerSpec(
            index=p.index,
            goal=p.goal if p.HasField("goal") else None,
            # a proto map has no order: sort, so equal requests give identical answers
            goal_probs=dict(sorted(p.goal_probs.items())) if p.goal_probs else None,
        )
        for p in specs
    )


def _request(settings: Settings, observations: np.ndarray, seed_offset: int = 0) -> ActRequest:
    return ActRequest(
        env=settings.env,
        ego_goal=settings.ego_goal,
        observations=observations,
        partners=_partners(settings.partners),
        method=settings.method or DEFAULT_METHOD,  # type: ignore[arg-type]  # the engine checks it
        temperature=settings.temperature if settings.HasField("temperature") else None,
        regret_bound=settings.regret_bound if settings.HasField("regret_bound") else None,
        budget=settings.budget if settings.HasField("budget") else None,
        seed=settings.seed + seed_offset if settings.HasField("seed") else None,
        alias=settings.alias or DEFAULT_ALIAS,
        versions=dict(settings.versions),
    )


def _rows(state: pb.State) -> list[list[float]]:
    return [list(agent.values) for agent in state.agents]


def check_one_input(message: Row) -> bool:
    """Whether the row comes as a state; `InvalidRequest` when both forms are given (checked
    before the engine runs, so the REST API's field names apply unchanged)."""
    from_state = message.HasField("state")
    if from_state and len(message.observation):
        raise InvalidRequest("observation", "give exactly one of observation and state")
    return from_state


BATCH_SOURCES = ("observations", "states", "observation_matrix")


def batch_source(message: pb.ActBatchRequest) -> str:
    """The one input form of a batch: `observations` (also when none is given: the engine then
    reports an empty batch), `states` or `observation_matrix`; `InvalidRequest` for two."""
    given = [
        name
        for name, present in zip(
            BATCH_SOURCES,
            (message.observations, message.states, message.HasField("observation_matrix")),
            strict=True,
        )
        if present
    ]
    if len(given) > 1:
        field = "observation_matrix" if "observation_matrix" in given else "observations"
        raise InvalidRequest(
            field,
            f"give exactly one of observations, states and observation_matrix, got {given}",
        )
    return given[0] if given else "observations"


def _single_observation(env: str, message: pb.ActRequest | pb.EpisodeStep) -> np.ndarray:
    """The (1, D) ego observation from `observation`, or from `state` + `ego_index`."""
    if message.HasField("state"):
        return observations_from_states(env, [_rows(message.state)], message.ego_index)
    return np.asarray(message.observation, dtype=np.float64).reshape(1, -1)


def act_request(message: pb.ActRequest) -> ActRequest:
    """The engine request of one `Act` call (its settings converted once: `repeated`)."""
    observation = _single_observation(message.env, message)
    seed = message.seed if message.HasField("seed") else None
    request = repeated.request_with(message, lambda: _request(message, _NO_ROWS), observation, seed)
    spent = [message.budget_spent] if message.HasField("budget_spent") else None
    total = [message.budget_total] if message.HasField("budget_total") else None
    value = [message.budget_value] if message.HasField("budget_value") else None
    if spent is None and total is None and value is None:
        return request
    return replace(request, budget_spent=spent, budget_total=total, budget_value=value)


def episode_request(
    settings: pb.EpisodeSettings,
    step: pb.EpisodeStep,
    t: int,
    budget: tuple[float, float, float] | None = None,
) -> ActRequest:
    """Step t of an episode: the episode's settings, this step's observation, seed + t, and
    aail_budget's state (spent, total, value) carried from the last step (None at the first)."""
    observation = _single_observation(settings.env, step)
    seed = settings.seed + t if settings.HasField("seed") else None
    request = repeated.request_with(
        settings, lambda: _request(settings, _NO_ROWS), observation, seed
    )
    if budget is None:
        return request
    return replace(
        request, budget_spent=[budget[0]], budget_total=[budget[1]], budget_value=[budget[2]]
    )


def act_batch_request(message: pb.ActBatchRequest, source: str) -> ActRequest:
    """The engine request of a batch given in its input form `source` (`batch_source`)."""
    return _with_budget(message, _batch_rows(message, source))


def _batch_rows(message: pb.ActBatchRequest, source: str) -> np.ndarray:
    """The batch's observations from its input form `source`."""
    if source == "observation_matrix":
        return _matrix(message.observation_matrix)
    if source == "states":
        states = [_rows(s) for s in message.states]
        return observations_from_states(message.env, states, message.ego_index)
    return _vectors([row.values for row in message.observations])


def _vectors(rows: Sequence[Any]) -> np.ndarray:
    lengths = set(map(len, rows))
    if len(lengths) > 1:
        raise InvalidRequest("observations", f"rows of different lengths {sorted(lengths)}")
    width = lengths.pop() if lengths else 0
    # one pass over the rows' containers, no list in between (cheaper than a flat list
    # comprehension: `docs/performance.md`)
    flat = np.fromiter(chain.from_iterable(rows), dtype=np.float64, count=len(rows) * width)
    return flat.reshape(len(rows), width)


def _with_budget(message: pb.ActBatchRequest, observations: np.ndarray) -> ActRequest:
    """The batch's engine request; aail_budget's carried state where the client sent it."""
    request = _request(message, observations)
    if not message.budget_spent and not message.budget_total and not message.budget_value:
        return request
    return replace(
        request,
        budget_spent=list(message.budget_spent) or None,
        budget_total=list(message.budget_total) or None,
        budget_value=list(message.budget_value) or None,
    )


def _matrix(matrix: pb.Matrix) -> np.ndarray:
    """The (rows, cols) observations of an `observation_matrix`, its shape checked."""
    for name, value in (("rows", matrix.rows), ("cols", matrix.cols)):
        if value < 1:
            raise InvalidRequest(f"observation_matrix.{name}", f"expected >= 1, got {value}")
    if matrix.rows * matrix.cols != len(matrix.values):
        raise InvalidRequest(
            "observation_matrix.values",
            f"expected rows x cols = {matrix.rows} x {matrix.cols} = "
            f"{matrix.rows * matrix.cols} values, got {len(matrix.values)}",
        )
    return np.array(matrix.values, dtype=np.float64).reshape(matrix.rows, matrix.cols)


def _is_inferred(partner: pb.PartnerSpec) -> bool:
    return partner.infer or (not partner.HasField("goal") and not partner.goal_probs)


def infers_goals(settings: pb.EpisodeSettings) -> bool:
    """Whether an episode with these settings keeps beliefs (a partner is inferred)."""
    return any(_is_inferred(p) for p in settings.partners)


def session_settings(settings: pb.EpisodeSettings) -> SessionSettings:
    """The settings of the episode's session; unset belief fields take the defaults."""
    partners = tuple(
        SessionPartner(
            index=p.index,
            goal=p.goal if p.HasField("goal") else None,
            goal_probs=dict(sorted(p.goal_probs.items())) if p.goal_probs else None,
            infer=p.infer,
        )
        for p in settings.partners
    )
    b = settings.belief
    belief = {
        k: getattr(b, k)
        for k in ("forgetting", "floor", "temperature", "noise", "prune_below", "prune_error")
        if b.HasField(k)
    }
    blend = {k: getattr(b, k) for k in ("blend_mass", "blend_max_goals") if b.HasField(k)}
    return SessionSettings(
        env=settings.env,
        ego_goal=settings.ego_goal,
        partners=partners,
        method=settings.method or DEFAULT_METHOD,  # type: ignore[arg-type]  # the session checks it
        temperature=settings.temperature if settings.HasField("temperature") else None,
        regret_bound=settings.regret_bound if settings.HasField("regret_bound") else None,
        budget=settings.budget if settings.HasField("budget") else None,
        seed=settings.seed if settings.HasField("seed") else None,
        alias=settings.alias or DEFAULT_ALIAS,
        versions=dict(settings.versions),
        belief=BeliefConfig(**belief),
        **blend,
    )


def session_step_inputs(env: str, step: pb.EpisodeStep) -> tuple[np.ndarray, list[Observed]]:
    """The step's ego observation (1, D) and its `observed` entries."""
    observation = _single_observation(env, step)
    observed = [
        Observed(o.index, o.action if o.HasField("action") else None) for o in step.observed
    ]
    return observation, observed


def session_response(settings: SessionSettings, answer: SessionStepResult) -> pb.ActResponse:
    """The step's action (as `act_response`) plus the beliefs."""
    message = pb.ActResponse()
    result = answer.result
    shared = pb.ActResponse(method=result.method, models=_models(result)).SerializeToString()
    meanings = env_runtime(settings.env).info.action_meanings
    _fill(message, result, shared, [p.index for p in settings.partners], meanings)
    for belief in answer.beliefs:
        out = message.beliefs.add(
            index=belief.index, entropy=belief.entropy, updates=belief.updates
        )
        for goal, prob in belief.top:
            out.top.add(goal=goal, prob=prob)
        if belief.observed_action is not None:
            out.observed_action = belief.observed_action
    return message


def renamed_for_transport(err: EngineError, *, from_state: bool) -> EngineError:
    """Blame the field the client sent for one row, `observation` or `state` (the engine names
    it `observations[0]`)."""
    field = err.field
    if field is None or not field.startswith(("observations", "states")):
        return err
    return err.renamed("state" if from_state else "observation")


def renamed_for_batch(err: EngineError, source: str) -> EngineError:
    """Blame the batch's input form `source` (`batch_source`): the engine's `observations[b]`
    becomes `states[b]` or `observation_matrix[b]`, its `observations` the whole input."""
    field = err.field
    if field is None or not field.startswith(("observations", "states")):
        return err
    rest = field.removeprefix("observations").removeprefix("states")
    return err.renamed(source + rest)


def _models(result: ActResult) -> list[pb.ModelUsed]:
    return _model_messages(result.models)


def _model_messages(models: Sequence[ModelUsed]) -> list[pb.ModelUsed]:
    out = []
    for m in models:
        model = pb.ModelUsed(role=m.role, name=m.name, version=m.version, sha256=m.sha256)
        model.goal = m.goal
        if m.partner_index is not None:
            model.partner_index = m.partner_index
        out.append(model)
    return out


def _fill(
    message: pb.ActResponse,
    result: ActResult,
    shared: bytes,
    partner_indices: Sequence[int],
    action_meanings: Sequence[str],
) -> None:
    """Write one result into `message`. `shared` is the serialized part every row of a request
    has in common (method, models): merging those bytes is cheaper than building the model
    messages again for each of a batch's rows."""
    message.MergeFromString(shared)
    message.probs.extend(result.probs)
    message.action = result.action
    message.greedy_action = result.greedy_action
    message.action_meaning = action_meanings[result.action]
    diagnostics = message.diagnostics
    diagnostics.task_entropy = result.task_entropy
    diagnostics.task_weight = result.task_weight
    for index, weight in zip(partner_indices, result.partner_weights, strict=True):
        diagnostics.partner_weights.add(index=index, weight=weight)
    if (
        result.budget_total is not None
        and result.budget_spent is not None
        and result.budget_value is not None
    ):
        message.budget.spent = result.budget_spent
        message.budget.total = result.budget_total
        message.budget.value = result.budget_value


def _shared(request: ActRequest, results: Sequence[ActResult]) -> tuple[bytes, list[int], Any]:
    shared = pb.ActResponse(method=results[0].method, models=_models(results[0]))
    meanings = env_runtime(request.env).info.action_meanings
    return shared.SerializeToString(), [p.index for p in request.partners], meanings


def act_response(request: ActRequest, result: ActResult) -> pb.ActResponse:
    message = pb.ActResponse()
    head = repeated.head_for(request, result, lambda: _shared(request, [result]))
    _fill(message, result, head.shared, head.partner_indices, head.action_meanings)
    return message


def act_batch_response(request: ActRequest, results: Sequence[ActResult]) -> pb.ActBatchResponse:
    """One response per row; the rows share one engine request, hence one model list."""
    batch = pb.ActBatchResponse()
    if results:
        shared = _shared(request, results)
        for result in results:
            _fill(batch.results.add(), result, *shared)
    return batch


def act_columns_response(request: ActRequest, columns: ActColumns) -> pb.ActBatchResponse:
    """The batch as one `ActColumns` message: each array written with one `extend`."""
    batch = pb.ActBatchResponse()
    out = batch.columns
    out.method = columns.method
    out.models.extend(_model_messages(columns.models))
    out.rows, out.n_actions = columns.probs.shape
    out.probs.extend(columns.probs.ravel())
    out.actions.extend(columns.actions)
    out.greedy_actions.extend(columns.greedy_actions)
    meanings = env_runtime(request.env).info.action_meanings
    out.action_meanings.extend([meanings[a] for a in columns.actions.tolist()])
    out.task_entropies.extend(columns.task_entropies)
    out.task_weights.extend(columns.task_weights)
    out.partner_indices.extend([p.index for p in request.partners])
    out.partner_weights.extend(columns.partner_weights.ravel())
    if (
        columns.budget_spent is not None
        and columns.budget_total is not None
        and columns.budget_value is not None
    ):
        out.budget_spent.extend(columns.budget_spent)
        out.budget_total.extend(columns.budget_total)
        out.budget_value.extend(columns.budget_value)
    return batch


def env_info(info: EnvInfo) -> pb.EnvInfo:
    layouts: list[Any] = [
        pb.ObservationLayout(
            n_agents=n, obs_dim=info.obs_dims[n], features=info.observation_layouts[n]
        )
        for n in sorted(info.obs_dims)
    ]
    return pb.EnvInfo(
        name=info.name,
        goals=info.goals,
        action_meanings=info.action_meanings,
        max_agents=info.max_agents,
        observation_layouts=layouts,
        state_layout=info.state_layout or (),
        pair_obs_dim=info.pair_obs_dim,
        methods=info.methods,
    )
