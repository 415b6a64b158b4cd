"""Model names, aliases, references and their validation.

| thing      | form                                   | example                   |
|------------|----------------------------------------|---------------------------|
| model name | segments joined by "/", each           | `particle/task/a3`        |
|            | `[A-Za-z0-9][A-Za-z0-9_.+-]*`          | `particle/task/4`         |
| alias      | `[a-z][a-z0-9_-]*`, at most 64 chars   | `production`, `latest`    |
| ref        | `name@alias`, `name/version` or `name` | `particle/task/a3@latest` |
|            | (a bare name means `name@production`)  | `particle/task/a3/2`      |
| tag key    | `[A-Za-z0-9_.:/-]`, 1..64 chars        | `team`                    |
| version    | an integer in 1..`MAX_VERSION`         | `3`                       |
| idempotency key | `[A-Za-z0-9._:-]`, 1..128 chars   | a UUID, a sha256          |

Version numbers live in Integer columns (32 bits on PostgreSQL), so the API's range is
1..2^31-1 (`MAX_VERSION`) on every backend: a number past it is an `InvalidArgument` (422) before
any SQL runs, a number within it that no version has is `NotFound` (404). `parse_ref` refuses a
ref whose version reading is past the range (`name/99999999999` is not read as a model name
instead: such a name would be a model nobody can address by version).

Refs whose last segment is a number have two readings: `particle/task/4` is version 4 of
`particle/task`, or the model `particle/task/4` (a row goal of the particle world) at
`production`. The store keeps them apart by refusing a model name that is a path prefix of
another (`particle/task` and `particle/task/4` never both exist), so at most one reading names an
existing model; `ref_candidates` lists the readings and `ModelStore.resolve` picks that one.
`parse_ref` alone (used where a version is meant, e.g. lineage parents) takes the version reading.

Why segments start with a letter or digit: the REST API separates a name from its sub-resources
with a `/-/` segment (`/models/particle/task/a3/-/versions/2`), which no name can contain.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from model_store.errors import InvalidArgument, brief

DEFAULT_ALIAS = "production"
LATEST_ALIAS = "latest"
MAX_NAME_LENGTH = 200
MAX_VERSION = 2**31 - 1  # model_versions.version and friends are Integer columns
MAX_SIZE = 2**31 - 1  # a model's obs_dim and n_actions (Integer columns too)

_SEGMENT = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.+-]*")
_ALIAS = re.compile(r"[a-z][a-z0-9_-]{0,63}")
_ENV = re.compile(r"[a-z][a-z0-9_-]{0,63}")
_GOAL = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}")
_TAG_KEY = re.compile(r"[A-Za-z0-9_.:/-]{1,64}")
MAX_TAG_VALUE = 1000
_IDEMPOTENCY_KEY = re.compile(r"[A-Za-z0-9._:-]{1,128}")


def validate_model_name(name: str, field: str = "name") -> str:
    """Return `name` unchanged or raise InvalidArgument naming `field`."""
    if not isinstance(name, str) or not name:
        raise InvalidArgument(f"{field}: a model name must be a non-empty string", field=field)
    if len(name) > MAX_NAME_LENGTH:
        raise InvalidArgument(f"{field}: longer than {MAX_NAME_LENGTH} characters", field=field)
    for segment in name.split("/"):
        if not _SEGMENT.fullmatch(segment):
            raise InvalidArgument(
                f"{field}: segment {brief(segment)} of {brief(name)} must match [A-Za-z0-9][A-Za-z0-9_.+-]*",
                field=field,
            )
    return name


def path_prefixes(name: str) -> list[str]:
    """`a/b/c` -> [`a`, `a/b`]: the names that would make refs to `name` ambiguous."""
    segments = name.split("/")
    return ["/".join(segments[:i]) for i in range(1, len(segments))]


def validate_alias(alias: str, field: str = "alias") -> str:
    if not isinstance(alias, str) or not _ALIAS.fullmatch(alias):
        raise InvalidArgument(
            f"{field}: alias {brief(alias)} must match [a-z][a-z0-9_-]* (at most 64 characters)",
            field=field,
        )
    return alias


def validate_env(env: str, field: str = "env") -> str:
    if not isinstance(env, str) or not _ENV.fullmatch(env):
        raise InvalidArgument(f"{field}: env {brief(env)} must match [a-z][a-z0-9_-]*", field=field)
    return env


def validate_goal(goal: str, field: str = "goal") -> str:
    if not isinstance(goal, str) or not _GOAL.fullmatch(goal):
        raise InvalidArgument(
            f"{field}: goal {brief(goal)} must match [A-Za-z0-9][A-Za-z0-9_.-]*", field=field
        )
    return goal


def validate_tags(tags: Mapping[str, str], field: str = "tags") -> dict[str, str]:
    if not isinstance(tags, Mapping):
        raise InvalidArgument(f"{field}: expected a mapping of strings to strings", field=field)
    for key, value in tags.items():
        if not isinstance(key, str) or not _TAG_KEY.fullmatch(key):
            raise InvalidArgument(
                f"{field}: tag key {brief(key)} must match [A-Za-z0-9_.:/-]{{1,64}}",
                field=f"{field}.{key}",
            )
        if not isinstance(value, str) or len(value) > MAX_TAG_VALUE:
            raise InvalidArgument(
                f"{field}.{key}: a string of at most {MAX_TAG_VALUE} characters",
                field=f"{field}.{key}",
            )
        validate_text(value, f"{field}.{key}")
    return dict(tags)


def validate_text(value: object, field: str) -> str:
    """A string for a text column: any characters but NUL, which PostgreSQL's text type cannot
    hold (SQLite could; refusing it on both keeps the backends alike)."""
    if not isinstance(value, str):
        raise InvalidArgument(f"{field}: expected a string", field=field)
    if "\x00" in value:
        raise InvalidArgument(f"{field}: must not contain NUL (\\x00) characters", field=field)
    return value


def validate_idempotency_key(key: str, field: str = "idempotency_key") -> str:
    if not isinstance(key, str) or not _IDEMPOTENCY_KEY.fullmatch(key):
        raise InvalidArgument(
            f"{field}: {brief(key)} must match [A-Za-z0-9._:-]{{1,128}}", field=field
        )
    return key


def task_model_name(env: str, goal: str) -> str:
    """`{env}/task/{goal}`: the task network of an agent with `goal`."""
    return validate_model_name(f"{validate_env(env)}/task/{validate_goal(goal)}")


def impact_model_name(env: str, goal: str) -> str:
    """`{env}/impact/{goal}`: the impact network for a *partner* whose goal is `goal`."""
    return validate_model_name(f"{validate_env(env)}/impact/{validate_goal(goal)}")


def monitor_model_name(env: str, goal: str) -> str:
    """`{env}/monitor/{goal}`: which actions keep the reached goal of an agent with `goal`."""
    return validate_model_name(f"{validate_env(env)}/monitor/{validate_goal(goal)}")


def joint_model_name(env: str, ego: str, partners: Sequence[str]) -> str:
    """`{env}/joint/{ego}+{p1}+...`: the joint-learner baseline for one goal combination."""
    if isinstance(partners, str) or not partners:
        raise InvalidArgument("partners: expected a non-empty list of goals", field="partners")
    goals = [validate_goal(ego, "ego"), *(validate_goal(p, "partners") for p in partners)]
    return validate_model_name(f"{validate_env(env)}/joint/{'+'.join(goals)}")


@dataclass(frozen=True)
class Ref:
    """A parsed reference: exactly one of `version` and `alias` is set."""

    name: str
    version: int | None = None
    alias: str | None = None

    def __str__(self) -> str:
        return (
            f"{self.name}/{self.version}"
            if self.version is not None
            else f"{self.name}@{self.alias}"
        )


def parse_ref(ref: str, field: str = "ref") -> Ref:
    """Parse `name@alias`, `name/version` or a bare `name` (= `name@production`); a numeric
    last segment is read as a version (see the module docstring)."""
    if not isinstance(ref, str) or not ref:
        raise InvalidArgument(
            f"{field}: expected 'name@alias', 'name/version' or 'name'", field=field
        )
    if "@" in ref:
        name, _, alias = ref.rpartition("@")
        return Ref(validate_model_name(name, field), alias=validate_alias(alias, field))
    head, _, last = ref.rpartition("/")
    if head and last.isascii() and last.isdigit():
        if len(last) > 12 or not 1 <= int(last) <= MAX_VERSION:  # no int() of a huge string
            raise InvalidArgument(
                f"{field}: a version is an integer in 1..{MAX_VERSION}, got {brief(last)}",
                field=field,
            )
        version = int(last)
        return Ref(validate_model_name(head, field), version=version)
    return Ref(validate_model_name(ref, field), alias=DEFAULT_ALIAS)


def ref_candidates(ref: str, field: str = "ref") -> tuple[Ref, ...]:
    """Every reading of `ref`: two when its last segment is a number, else one."""
    first = parse_ref(ref, field)
    if first.version is None:
        return (first,)
    try:
        return (first, Ref(validate_model_name(ref, field), alias=DEFAULT_ALIAS))
    except InvalidArgument:
        return (first,)
