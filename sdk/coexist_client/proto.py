"""Client-side translation between the REST JSON bodies (`coexist_client.bodies`) and protobuf.

| function              | from                        | to                                |
|-----------------------|-----------------------------|-----------------------------------|
| `act_request`         | `act_body(...)` dict        | `coexist.v1.ActRequest`           |
| `act_batch_request`   | `act_batch_body(...)` dict  | `coexist.v1.ActBatchRequest`      |
|                       |                             | (observations as one `Matrix`)    |
| `episode_step`        | settings and/or observation,| `coexist.v1.EpisodeStep`          |
|                       | observed actions            |                                   |
| `action_from_proto`   | `coexist.v1.ActResponse`    | `coexist_client.types.Action`       |
| `columns_from_proto`  | `coexist.v1.ActColumns`     | `coexist_client.types.ActionColumns`|
| `blame_observations`  | an error naming             | the same naming `observations`    |
|                       | `observation_matrix...`     | (the field the SDK user gave)     |
| `env_from_proto`      | `coexist.v1.EnvInfo`        | `coexist_client.types.EnvInfo`      |
"""

from __future__ import annotations

from typing import Any

import numpy as np

from coexist_client.errors import CoexistError, InvalidArgument
from coexist_client.gen.coexist.v1 import policy_pb2 as pb
from coexist_client.types import (
    COLUMN_FIELDS,
    Action,
    ActionColumns,
    Budget,
    Diagnostics,
    EnvInfo,
    ModelUsed,
    PartnerBelief,
    PartnerWeight,
)

_SETTINGS = ("env", "ego_goal", "method", "alias")


def _settings_kwargs(body: dict[str, Any]) -> dict[str, Any]:
    """Keyword arguments of the settings fields shared by ActRequest, ActBatchRequest and
    EpisodeSettings (unset optionals are left out, so `HasField` tells them apart)."""
    kwargs: dict[str, Any] = {k: body[k] for k in _SETTINGS}
    partners = []
    for k, spec in enumerate(body["partners"]):
        try:
            partner = pb.PartnerSpec(index=int(spec["index"]))
            if spec.get("goal") is not None:
                partner.goal = spec["goal"]
            if spec.get("goal_probs") is not None:
                partner.goal_probs.update(spec["goal_probs"])
            partner.infer = bool(spec.get("infer", False))
        except (TypeError, ValueError, KeyError) as err:
            field = f"partners[{k}]"
            raise InvalidArgument("invalid_argument", f"{field}: {err}", field) from None
        partners.append(partner)
    kwargs["partners"] = partners
    kwargs["versions"] = body["versions"]
    for key in ("temperature", "regret_bound", "budget", "seed"):
        if body.get(key) is not None:
            kwargs[key] = body[key]
    if body.get("belief"):  # episodes only (session_body); unset fields: the server's defaults
        kwargs["belief"] = _build(pb.BeliefSettings, dict(body["belief"]))
    return kwargs


def _build(message_class: Any, kwargs: dict[str, Any]) -> Any:
    try:
        return message_class(**kwargs)
    except (TypeError, ValueError) as err:  # e.g. a seed beyond int64, a non-string goal
        raise InvalidArgument("invalid_argument", f"request: {err}", "request") from None


def _state(rows: list[list[float]]) -> pb.State:
    return pb.State(agents=[pb.Vector(values=row) for row in rows])


def _observation_kwargs(fields: dict[str, Any]) -> dict[str, Any]:
    if "observation" in fields:
        return {"observation": fields["observation"]}
    return {"state": _state(fields["state"]), "ego_index": fields["ego_index"]}


def act_request(body: dict[str, Any]) -> pb.ActRequest:
    kwargs = _settings_kwargs(body)
    kwargs.update(_observation_kwargs(body))
    for key in ("budget_spent", "budget_total", "budget_value"):  # aail_budget's carried state
        if body.get(key) is not None:
            kwargs[key] = body[key]
    message: pb.ActRequest = _build(pb.ActRequest, kwargs)
    return message


def act_batch_request(body: dict[str, Any]) -> pb.ActBatchRequest:
    """Observations travel as one `observation_matrix` (one flat array: far cheaper to encode
    and decode than a `Vector` per row); `"format": "columns"` asks for `ActColumns`."""
    kwargs = _settings_kwargs(body)
    if body.get("format") == "columns":
        kwargs["format"] = pb.BATCH_FORMAT_COLUMNS
    if "observations" in body:
        obs_BD = np.asarray(body["observations"], dtype=np.float64)  # 2-D: act_batch_body
        rows, cols = obs_BD.shape
        kwargs["observation_matrix"] = pb.Matrix(rows=rows, cols=cols, values=obs_BD.ravel())
    else:
        kwargs["states"] = [_state(s) for s in body["states"]]
        kwargs["ego_index"] = body["ego_index"]
    for key in ("budget_spent", "budget_total", "budget_value"):  # aail_budget's, per row
        if body.get(key) is not None:
            kwargs[key] = body[key]
    message: pb.ActBatchRequest = _build(pb.ActBatchRequest, kwargs)
    return message


def episode_step(
    settings: dict[str, Any] | None,
    fields: dict[str, Any],
    observed: list[dict[str, Any]] | None = None,
) -> pb.EpisodeStep:
    """One step; `settings` (a `session_body` dict) only on the first step; `observed` in the
    `observed_entries` form."""
    kwargs = _observation_kwargs(fields)
    if settings is not None:
        kwargs["settings"] = _build(pb.EpisodeSettings, _settings_kwargs(settings))
    if observed:
        kwargs["observed"] = [_build(pb.ObservedAction, dict(entry)) for entry in observed]
    message: pb.EpisodeStep = _build(pb.EpisodeStep, kwargs)
    return message


def action_from_proto(response: pb.ActResponse) -> Action:
    d = response.diagnostics
    return Action(
        probs=tuple(response.probs),
        action=response.action,
        greedy_action=response.greedy_action,
        action_meaning=response.action_meaning,
        method=response.method,
        diagnostics=Diagnostics(
            task_entropy=d.task_entropy,
            task_weight=d.task_weight,
            partner_weights=tuple(PartnerWeight(w.index, w.weight) for w in d.partner_weights),
        ),
        models=tuple(_model_from_proto(m) for m in response.models),
        beliefs=tuple(
            PartnerBelief(
                index=b.index,
                top=tuple((g.goal, g.prob) for g in b.top),
                entropy=b.entropy,
                observed_action=b.observed_action if b.HasField("observed_action") else None,
                updates=b.updates,
            )
            for b in response.beliefs
        ),
        budget=Budget(response.budget.spent, response.budget.total, response.budget.value)
        if response.HasField("budget")
        else None,
    )


def _model_from_proto(m: pb.ModelUsed) -> ModelUsed:
    return ModelUsed(
        role=m.role,
        name=m.name,
        version=m.version,
        sha256=m.sha256,
        partner_index=m.partner_index if m.HasField("partner_index") else None,
        goal=m.goal or None,
    )


def columns_from_proto(columns: pb.ActColumns) -> ActionColumns:
    return ActionColumns.from_sequences(
        rows=columns.rows,
        method=columns.method,
        models=[_model_from_proto(m) for m in columns.models],
        budget_spent=columns.budget_spent,
        budget_total=columns.budget_total,
        budget_value=columns.budget_value,
        **{name: getattr(columns, name) for name in COLUMN_FIELDS},
    )


def blame_observations(err: CoexistError) -> CoexistError:
    """`err` naming `observations` where the server named the matrix the SDK sent them in:
    `observation_matrix[b]` becomes `observations[b]`, the matrix or its shape `observations`."""
    field = err.field
    if field is None or not field.startswith("observation_matrix"):
        return err
    rest = field.removeprefix("observation_matrix")
    renamed = "observations" + (rest if rest.startswith("[") else "")
    message = err.message.removeprefix(f"{field}:")
    if message != err.message:
        message = f"{renamed}:{message}"
    return type(err)(err.code, message, renamed)


def env_from_proto(env: pb.EnvInfo) -> EnvInfo:
    return EnvInfo(
        name=env.name,
        goals=tuple(env.goals),
        action_meanings=tuple(env.action_meanings),
        max_agents=env.max_agents,
        obs_dims={layout.n_agents: layout.obs_dim for layout in env.observation_layouts},
        observation_layouts={
            layout.n_agents: tuple(layout.features) for layout in env.observation_layouts
        },
        state_layout=tuple(env.state_layout) or None,
        pair_obs_dim=env.pair_obs_dim,
        methods=tuple(env.methods),
    )
