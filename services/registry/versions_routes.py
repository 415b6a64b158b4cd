"""Versions and aliases of a model, under `/models/{name}/-/...`.

Model names contain slashes, so a name's sub-resources are separated from it by a `-` segment,
which no model name can contain (`model_store.naming`):

    /v1/registry/models/particle/task/a3/-/versions/2/weights

Upload (`POST .../-/versions`) takes `multipart/form-data` with the parts `spec` (the architecture
JSON), `weights` (the safetensors file) and optionally `lineage` (JSON); the body is read with a
size cap and refused with 413 as soon as it is over the limit. An `Idempotency-Key` header makes
the upload safe to retry when its answer was lost: a key the model already has answers the
version it registered (201, the same body; aliases untouched), a key reused for other weights
or another spec is a 409 (`ModelStore.register_version`).

The registry holds only networks the engine can serve: an upload is run through the engine's own
forward on probe inputs first (`services.engine.admission`) and refused with 422
naming `weights` when its Q-values overflow; an alias is moved only to a version that loads and
passes the same probe (409 otherwise, the alias stays where it was), so `production` never points
at a network that would fail every request.
"""

from __future__ import annotations

import json
from typing import Annotated, Any

from fastapi import APIRouter, Header, Path, Query, Request, Response, status
from starlette.concurrency import run_in_threadpool

from model_store.entities import Lineage
from model_store.errors import ArtifactTooLarge, InvalidArtifact
from model_store.naming import MAX_VERSION
from services.deps import ReadAuth, SettingsDep, StoreDep, WriteAuth
from services.engine.admission import refuse_unservable_upload, refuse_unservable_version
from services.registry.downloads import DOWNLOADS, WeightsResponse
from services.registry.errors import ERROR_RESPONSES, ApiError
from services.registry.multipart import Part, boundary_of, parse_form_data
from services.registry.schemas import AliasOut, AliasSet, VersionOut
from services.rest.json_body import FastJsonRoute, has_lone_surrogate

router = APIRouter(responses=ERROR_RESPONSES, route_class=FastJsonRoute)
FORM_OVERHEAD_BYTES = 1 << 20  # room for the spec, lineage and part headers beside the weights
MODEL = "/models/{name:path}/-"
VersionNumber = Annotated[
    int, Path(ge=1, le=MAX_VERSION, description=f"version number, 1..{MAX_VERSION}")
]

_UPLOAD_BODY: dict[str, Any] = {
    "requestBody": {
        "required": True,
        "content": {
            "multipart/form-data": {
                "schema": {
                    "type": "object",
                    "required": ["spec", "weights"],
                    "properties": {
                        "spec": {"type": "string", "description": "architecture spec (JSON)"},
                        "lineage": {"type": "string", "description": "lineage (JSON object)"},
                        "weights": {"type": "string", "format": "binary"},
                    },
                }
            }
        },
    }
}


async def _read_capped(request: Request, limit: int) -> bytes:
    declared = request.headers.get("content-length")
    if declared is not None and declared.isdigit() and int(declared) > limit:
        raise ArtifactTooLarge(
            f"body: {declared} bytes is over the limit of {limit}", field="weights"
        )
    body = bytearray()
    async for chunk in request.stream():
        body += chunk
        if len(body) > limit:
            raise ArtifactTooLarge(f"body: over the limit of {limit} bytes", field="weights")
    return bytes(body)


def _json_part(parts: dict[str, Part], name: str, *, required: bool) -> Any:
    if name not in parts:
        if required:
            raise InvalidArtifact(f"{name}: missing form field", field=name)
        return None
    try:
        value = json.loads(parts[name].data)
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InvalidArtifact(f"{name}: not valid JSON ({exc})", field=name) from None
    if has_lone_surrogate(value):  # `\ud800`: no UTF-8 encoder (database, answer) can write it
        raise InvalidArtifact(f"{name}: not valid JSON (a lone surrogate escape)", field=name)
    return value


@router.post(
    f"{MODEL}/versions",
    response_model=VersionOut,
    status_code=status.HTTP_201_CREATED,
    openapi_extra=_UPLOAD_BODY,
    responses={
        409: {"description": "the Idempotency-Key registered other weights or another spec"},
        413: {"description": "weights over the size limit"},
    },
    tags=["versions"],
)
async def upload_version(
    name: str,
    request: Request,
    store: StoreDep,
    settings: SettingsDep,
    _: WriteAuth,
    response: Response,
    alias: Annotated[list[str], Query(description="aliases to set besides `latest`")] = [],  # noqa: B006
    idempotency_key: Annotated[
        str | None,
        Header(
            description="makes a retry safe: the same key answers the version it registered "
            "(1-128 of A-Za-z0-9._:-; a UUID per upload, or the weights' sha256)",
        ),
    ] = None,
) -> VersionOut:
    """Register a new version (numbered automatically) from a spec and a safetensors file;
    `latest` and the `alias` query parameters then point at it. With `Idempotency-Key`, a retry
    answers the version the key registered."""
    boundary = boundary_of(request.headers.get("content-type", ""))
    if boundary is None:
        raise ApiError(415, "unsupported_media_type", "expected multipart/form-data", field="body")
    body = await _read_capped(request, settings.max_artifact_bytes + FORM_OVERHEAD_BYTES)
    parts = parse_form_data(boundary, body)
    spec = _json_part(parts, "spec", required=True)
    lineage_json = _json_part(parts, "lineage", required=False)
    if lineage_json is None:
        lineage_json = {}
    if "weights" not in parts:
        raise InvalidArtifact("weights: missing form field (the safetensors file)", field="weights")
    if isinstance(lineage_json, dict):
        lineage_json.setdefault("registered_by", "rest-api")
    lineage = Lineage.from_json(lineage_json)
    weights = parts["weights"].data
    if len(weights) > settings.max_artifact_bytes:
        raise ArtifactTooLarge(
            f"weights: {len(weights)} bytes is over the limit of {settings.max_artifact_bytes}",
            field="weights",
        )
    await run_in_threadpool(refuse_unservable_upload, spec, weights)
    version = await run_in_threadpool(
        store.register_version,
        name,
        spec=spec,
        weights=weights,
        lineage=lineage,
        aliases=("latest", *alias),
        idempotency_key=idempotency_key,
    )
    response.headers["Location"] = f"/v1/registry/models/{name}/-/versions/{version.version}"
    return VersionOut.of(version)


@router.get(f"{MODEL}/versions", response_model=list[VersionOut], tags=["versions"])
def list_versions(name: str, store: StoreDep, _: ReadAuth) -> list[VersionOut]:
    """All versions, newest first."""
    return [VersionOut.of(v) for v in store.list_versions(name)]


@router.get(f"{MODEL}/versions/{{version}}", response_model=VersionOut, tags=["versions"])
def get_version(name: str, version: VersionNumber, store: StoreDep, _: ReadAuth) -> VersionOut:
    """A version's metadata: spec, sha256, size, status and lineage."""
    return VersionOut.of(store.get_version(name, version))


@router.get(
    f"{MODEL}/versions/{{version}}/weights",
    response_class=Response,
    responses={200: {"content": {"application/octet-stream": {}}}, 304: {}},
    tags=["versions"],
)
async def download_weights(
    name: str,
    version: VersionNumber,
    store: StoreDep,
    _: ReadAuth,
    if_none_match: Annotated[str | None, Header()] = None,
) -> Response:
    """The safetensors bytes (checksum verified), with `X-Checksum-Sha256` and an ETag; sent in
    chunks as the client reads them (`services.registry.downloads`)."""
    meta = await run_in_threadpool(store.get_version, name, version)
    etag = f'"{meta.sha256}"'
    if if_none_match is not None and etag in [t.strip() for t in if_none_match.split(",")]:
        return Response(status_code=status.HTTP_304_NOT_MODIFIED, headers={"ETag": etag})
    weights = await DOWNLOADS.open(store, name, version)
    filename = f"{name.replace('/', '_')}_v{version}.safetensors"
    return WeightsResponse(
        weights,
        headers={
            "X-Checksum-Sha256": weights.sha256,
            "ETag": etag,
            "Content-Disposition": f'attachment; filename="{filename}"',
        },
    )


@router.post(f"{MODEL}/versions/{{version}}/archive", response_model=VersionOut, tags=["versions"])
def archive_version(name: str, version: VersionNumber, store: StoreDep, _: WriteAuth) -> VersionOut:
    """Archive (keeps the data); refused with 409 while an alias points at the version."""
    return VersionOut.of(store.archive_version(name, version))


@router.delete(
    f"{MODEL}/versions/{{version}}", status_code=status.HTTP_204_NO_CONTENT, tags=["versions"]
)
def delete_version(name: str, version: VersionNumber, store: StoreDep, _: WriteAuth) -> Response:
    """Delete a version and its data; refused with 409 while an alias points at it (move or
    delete the alias first), as archiving is."""
    store.delete_version(name, version)
    return Response(status_code=status.HTTP_204_NO_CONTENT)


@router.put(f"{MODEL}/aliases/{{alias}}", response_model=AliasOut, tags=["aliases"])
def set_alias(name: str, alias: str, body: AliasSet, store: StoreDep, _: WriteAuth) -> AliasOut:
    """Create or move an alias (atomically) to a ready version the engine can serve."""
    refuse_unservable_version(store, name, body.version, alias)
    store.set_alias(name, alias, body.version)
    return AliasOut(name=name, alias=alias, version=body.version)


@router.delete(
    f"{MODEL}/aliases/{{alias}}", status_code=status.HTTP_204_NO_CONTENT, tags=["aliases"]
)
def delete_alias(name: str, alias: str, store: StoreDep, _: WriteAuth) -> Response:
    store.delete_alias(name, alias)
    return Response(status_code=status.HTTP_204_NO_CONTENT)


@router.get("/resolve", response_model=VersionOut, tags=["versions"])
def resolve(
    store: StoreDep,
    _: ReadAuth,
    ref: Annotated[str, Query(description="`name@alias`, `name/3`, or `name` (= @production)")],
) -> VersionOut:
    return VersionOut.of(store.resolve(ref))
