"""What a client sends again with every call, converted once.

A robot calls `Act` every control step with the same env, goals, partners, method and alias;
only the observation (and perhaps the seed) changes, and the answer names the same models each
time. Converting those settings to the engine's `ActRequest` and serialising the answer's
method and models cost more than the blend's arithmetic for one partner
(`docs/performance.md`), so both are remembered in small bounded maps:

| memo        | key                                          | value                               |
|-------------|----------------------------------------------|-------------------------------------|
| `_SETTINGS` | the message's bytes without the per-call     | an `ActRequest` whose observation   |
|             | fields (observation, state, seed, budget     | and seed each call fills in         |
|             | state)                                       |                                     |
| `_HEADS`    | env, method, the request's partners tuple    | the serialized method + models, the |
|             | and its result's models, by identity         | partner indices, action meanings    |

A settings message that fails conversion (an unknown field value is the engine's to judge; an
`infer` flag on a unary call is refused here) raises before anything is remembered. Identity
keys are safe because the entry keeps the keyed objects alive and is used only when they are
the very objects of the call. The maps are cleared when full (a client that varies its settings
on every call gains nothing and loses nothing but the look-up).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, NamedTuple, TypeVar

import numpy as np

from services.engine import ActRequest, ActResult, ModelUsed
from services.grpc_api.gen.coexist.v1 import policy_pb2 as pb

MEMO_MAX = 256
_PER_CALL_FIELDS = (
    "observation",
    "state",
    "seed",
    "budget_spent",
    "budget_total",
    "budget_value",
)

K = TypeVar("K")
V = TypeVar("V")


def _remembered(memo: dict[K, V], key: K, make: Callable[[], V]) -> V:
    value = memo.get(key)
    if value is None:
        value = make()
        if len(memo) >= MEMO_MAX:
            memo.clear()
        memo[key] = value
    return value


_SETTINGS: dict[bytes, ActRequest] = {}


def request_with(
    message: pb.ActRequest | pb.EpisodeSettings,
    convert: Callable[[], ActRequest],
    observations: np.ndarray,
    seed: int | None,
) -> ActRequest:
    """`convert()`'s request for `message`'s settings, remembered by them, with this call's
    observations and seed."""
    settings = type(message)()
    settings.CopyFrom(message)
    for name in _PER_CALL_FIELDS:
        if name in settings.DESCRIPTOR.fields_by_name:
            settings.ClearField(name)
    key = settings.DESCRIPTOR.full_name.encode() + settings.SerializeToString(deterministic=True)
    t = _remembered(_SETTINGS, key, convert)
    return ActRequest(
        env=t.env,
        ego_goal=t.ego_goal,
        observations=observations,
        partners=t.partners,
        method=t.method,
        temperature=t.temperature,
        regret_bound=t.regret_bound,
        budget=t.budget,
        seed=seed,
        alias=t.alias,
        versions=t.versions,
    )


class Head(NamedTuple):
    """What every answer to one request shape starts with."""

    partners: Any  # the request's partners tuple (kept alive: its id is part of the key)
    models: tuple[ModelUsed, ...]  # the same, for the models
    shared: bytes  # serialized `ActResponse` with method and models only
    partner_indices: list[int]
    action_meanings: Sequence[str]


_HEADS: dict[tuple[Any, ...], Head] = {}


def head_for(
    request: ActRequest, result: ActResult, make: Callable[[], tuple[bytes, list[int], Any]]
) -> Head:
    """The answer head of (`request`, `result`), from `make()` unless remembered."""
    key = (request.env, result.method, id(request.partners), *map(id, result.models))
    head = _HEADS.get(key)
    if (
        head is not None
        and head.partners is request.partners
        and len(head.models) == len(result.models)
        and all(a is b for a, b in zip(head.models, result.models, strict=True))
    ):
        return head
    head = Head(request.partners, tuple(result.models), *make())
    if len(_HEADS) >= MEMO_MAX:
        _HEADS.clear()
    _HEADS[key] = head
    return head
