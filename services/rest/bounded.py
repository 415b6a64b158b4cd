"""Request-body types whose validation stops at the first problem, so a body of a million bad
values costs one error, not a million (pydantic collects every error by default: a 1 MiB array
of strings took seconds of the event loop to refuse, and its 422 listed each one).

| type / base       | what                                                               |
|-------------------|--------------------------------------------------------------------|
| `RequestBody`     | base of the request models: unknown fields refused (`extra`), and  |
|                   | an object of more than `MAX_KEYS` keys is one error                |
| `Vector`, `Matrix`, `Tensor3` | lists of numbers that stop at the first non-number      |
| `VersionPins`, `GoalProbs`, `Tags` | mappings: more entries than their bound is one     |
|                   | error, before any entry is checked (pydantic's own `max_length`    |
|                   | checks a mapping's entries first); the schema says `maxProperties` |
| `at_most(n)`      | a list of more than n entries is one error, before any is checked  |
| `FAIL_FAST`       | `Field(fail_fast=True)`: a list of models stops at the first bad one|

Bounds are generous next to what a request can use (the engine checks the values and names the
field); they exist to bound the work of refusing a body, not to define the API.
"""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, model_validator

MAX_KEYS = 64  # keys of one JSON object of a request body
MAX_PINS = 256  # pinned versions of one request (a session may pin every task and impact net)
MAX_GOALS = 1024  # entries of one goal distribution
MAX_TAGS = 64  # tags of one model
MAX_LIST = 64  # partners, observed actions, a model's goals
FAIL_FAST = Field(fail_fast=True)

Vector = Annotated[list[float], FAIL_FAST]
Matrix = Annotated[list[Vector], FAIL_FAST]
Tensor3 = Annotated[list[Matrix], FAIL_FAST]


def at_most(limit: int) -> Any:
    def check(value: Any) -> Any:
        if isinstance(value, dict | list) and len(value) > limit:
            raise ValueError(f"at most {limit} entries, got {len(value)}")
        return value

    return BeforeValidator(check)


def bounded_list(limit: int) -> Any:
    """`Field` of a list of at most `limit` entries (the schema's `maxItems`)."""
    return Field(max_length=limit, fail_fast=True)


VersionPins = Annotated[dict[str, int], Field(max_length=MAX_PINS), at_most(MAX_PINS)]
GoalProbs = Annotated[dict[str, float], Field(max_length=MAX_GOALS), at_most(MAX_GOALS)]
Tags = Annotated[dict[str, str], Field(max_length=MAX_TAGS), at_most(MAX_TAGS)]


class RequestBody(BaseModel):
    """A request body (or an object in one): unknown fields are refused, and an object of more
    than `MAX_KEYS` keys is refused whole before its fields are checked."""

    model_config = ConfigDict(extra="forbid")

    @model_validator(mode="before")
    @classmethod
    def _few_keys(cls, data: Any) -> Any:
        if isinstance(data, dict) and len(data) > MAX_KEYS:
            raise ValueError(f"at most {MAX_KEYS} fields, got {len(data)}")
        return data
