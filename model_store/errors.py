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
"""

from __future__ import annotations


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
