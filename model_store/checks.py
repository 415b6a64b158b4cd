"""What every store backend checks before it writes, whatever keeps its data: a new model's
fields, and a registration's aliases, idempotency key and lineage. Each failure is an
`InvalidArgument` (an `InvalidArtifact` for the lineage) naming the field, as `model_store.store`
promises; the weights and spec are `model_store.artifacts.check_artifact`'s."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from model_store.artifacts import check_lineage
from model_store.entities import MODEL_KINDS, Lineage
from model_store.errors import InvalidArgument, brief
from model_store.naming import (
    MAX_SIZE,
    validate_alias,
    validate_env,
    validate_goal,
    validate_idempotency_key,
    validate_model_name,
    validate_tags,
    validate_text,
)


def check_kind(kind: str) -> str:
    if kind not in MODEL_KINDS:
        raise InvalidArgument(f"kind: {brief(kind)} is not one of {MODEL_KINDS}", field="kind")
    return kind


def check_new_model(
    name: str,
    *,
    env: str,
    kind: str,
    goals: Sequence[str],
    obs_dim: int,
    n_actions: int,
    description: str,
    tags: Mapping[str, str] | None,
) -> tuple[list[str], dict[str, str]]:
    """`create_model`'s arguments checked; its goals as a list and its tags as a dict."""
    validate_model_name(name)
    validate_env(env)
    check_kind(kind)
    if isinstance(goals, str) or not goals:
        raise InvalidArgument("goals: expected a non-empty list of goals", field="goals")
    goal_list = [validate_goal(g, f"goals[{i}]") for i, g in enumerate(goals)]
    for key, value in (("obs_dim", obs_dim), ("n_actions", n_actions)):
        if not isinstance(value, int) or isinstance(value, bool) or not 1 <= value <= MAX_SIZE:
            raise InvalidArgument(
                f"{key}: expected an integer in 1..{MAX_SIZE}, got {brief(value)}", field=key
            )
    validate_text(description, "description")
    return goal_list, validate_tags(tags or {})


def check_registration(
    aliases: Sequence[str], idempotency_key: str | None, lineage: Lineage
) -> list[str]:
    """`register_version`'s arguments but the artifact checked; its aliases, each once."""
    if isinstance(aliases, str):
        raise InvalidArgument("aliases: expected a list of aliases", field="aliases")
    if idempotency_key is not None:
        validate_idempotency_key(idempotency_key)
    alias_list = [validate_alias(a, "aliases") for a in dict.fromkeys(aliases)]
    check_lineage(lineage)
    return alias_list
