"""Domain errors of the model store.

Every error a caller can act on is one of these; the REST layer maps them to HTTP status codes in
one table (`services/registry/errors.py`), the CLI to exit codes. Each carries `field`: the name of
the argument, spec key, tensor or lineage entry that was wrong, or None when no single field is to
blame.

| error              | meaning                                                | HTTP |
|--------------------|--------------------------------------------------------|------|
| NotFound           | unknown model, version or alias                        | 404  |
| Conflict           | the request contradicts the registry's state           | 409  |
| AlreadyExists      | (a Conflict) the model already exists                  | 409  |
| InvalidArgument    | a bad name, ref, page token, tag ... (also ValueError) | 422  |
| InvalidArtifact    | spec or weights rejected (names the field/tensor)      | 422  |
| ArtifactTooLarge   | weights over the store's size limit                    | 413  |
| ChecksumMismatch   | stored bytes no longer match their sha256              | 502  |
| SchemaTooNew       | the database was migrated by a newer coexist           | 503  |
| StoreUnavailable   | the database cannot be reached or has disappeared      | 503  |

Messages quote what the caller sent through `brief`, never whole: an error about a 10 MB name
must not be a 10 MB answer (nor overflow a gRPC trailer).
"""

from __future__ import annotations

import reprlib

ECHO_CHARS = 64  # how much of a value an error message quotes
MESSAGE_CHARS = 1000  # the most of a message (or field name) the transports send

_short = reprlib.Repr()
_short.maxstring = _short.maxother = _short.maxlong = ECHO_CHARS
_short.maxlist = _short.maxtuple = _short.maxdict = _short.maxset = 6
_short.maxlevel = 2


def brief(value: object, limit: int = ECHO_CHARS) -> str:
    """`repr(value)` of at most about `limit` characters: a longer string is cut after its first
    `limit` characters and says how long it was; containers show their first few items."""
    if isinstance(value, str | bytes):
        if len(value) <= limit:
            return repr(value)
        unit = "characters" if isinstance(value, str) else "bytes"
        return f"{value[:limit]!r}… ({len(value)} {unit})"
    if isinstance(value, int) and value.bit_length() > 4 * limit:  # repr refuses > 4300 digits
        return f"an integer of {value.bit_length()} bits"
    return _short.repr(value)


def clip(text: str, limit: int = MESSAGE_CHARS) -> str:
    """`text` cut to `limit` characters: the transports' last guard on what they echo."""
    return text if len(text) <= limit else f"{text[:limit]}… (cut at {limit} characters)"


class ModelStoreError(Exception):
    """Base class: `str(err)` is a message for a person, `field` what was wrong (or None)."""

    code = "model_store_error"

    def __init__(self, message: str, *, field: str | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.field = field


class NotFound(ModelStoreError):
    code = "not_found"


class Conflict(ModelStoreError):
    code = "conflict"


class AlreadyExists(Conflict):
    code = "already_exists"


class InvalidArgument(ModelStoreError, ValueError):
    code = "invalid_argument"


class InvalidArtifact(InvalidArgument):
    code = "invalid_artifact"


class ArtifactTooLarge(InvalidArtifact):
    code = "artifact_too_large"


class ChecksumMismatch(ModelStoreError):
    code = "checksum_mismatch"


class SchemaTooNew(ModelStoreError):
    code = "schema_too_new"


class StoreUnavailable(ModelStoreError):
    code = "store_unavailable"
