"""Errors of the inference engine: what a transport maps to a status code.

Every error carries `field` (the request field to blame, in the engine's naming: `observations[0]`,
`partners[1].goal_probs`, `temperature`, ... or None) and `message` (the reason, without the field);
`str(err)` is `"{field}: {message}"`. Transports may rename `field` (REST's single `/v1/act` calls
it `observation`) with `renamed()`.

| error              | meaning                                              | REST | gRPC             |
|--------------------|------------------------------------------------------|------|------------------|
| `InvalidRequest`   | the request itself is wrong (shape, NaN, unknown goal) | 422  | INVALID_ARGUMENT |
| `ModelNotFound`    | no network registered under the name / alias / version | 404  | NOT_FOUND        |
| `ModelUnavailable` | the store is down, or a stored network is unusable   | 503  | UNAVAILABLE      |
|                    | (checksum mismatch, spec that does not fit the env)  |      |                  |
"""

from __future__ import annotations

from model_store.errors import brief


class EngineError(Exception):
    """Base class of the engine's errors (see the module docstring)."""

    code = "engine_error"

    def __init__(self, field: str | None, message: str) -> None:
        super().__init__(f"{field}: {message}" if field else message)
        self.field = field
        self.message = message

    def renamed(self, field: str | None) -> EngineError:
        """A copy of this error blaming `field` instead (same class and message)."""
        clone = type(self).__new__(type(self))
        clone.__dict__.update(self.__dict__)
        clone.field = field
        clone.args = (f"{field}: {self.message}" if field else self.message,)
        return clone


class InvalidRequest(EngineError, ValueError):
    """A bad request: wrong shape, non-finite value, unknown env/goal/method, bad partner ..."""

    code = "invalid_request"


class ModelNotFound(EngineError, LookupError):
    """No network under `name` for `ref` (an alias or a pinned version)."""

    code = "model_not_found"

    def __init__(
        self, name: str, ref: str, *, field: str | None = None, message: str | None = None
    ) -> None:
        super().__init__(field, message or f"no model {brief(ref)} in the store")
        self.name = name
        self.ref = ref


class ModelUnavailable(EngineError):
    """The store cannot be reached, or the network stored under `name` cannot be served."""

    code = "model_unavailable"

    def __init__(self, name: str | None, message: str) -> None:
        super().__init__(None, message)
        self.name = name
