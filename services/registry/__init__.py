"""The model registry's HTTP API: one router under `/v1/registry`.

| method | path                                      | auth  | what                     |
|--------|-------------------------------------------|-------|--------------------------|
| GET    | /models?env=&kind=&goal=&tag=&page_token= | read  | list, filter, paginate   |
| POST   | /models                                   | write | create a model           |
| GET    | /models/{name}                            | read  | model + versions         |
| PATCH  | /models/{name}                            | write | description, tags        |
| DELETE | /models/{name}                            | write | model and all it owns    |
| POST   | /models/{name}/-/versions                 | write | upload (multipart)       |
| GET    | /models/{name}/-/versions                 | read  | versions, newest first   |
| GET    | /models/{name}/-/versions/{v}             | read  | metadata + lineage       |
| GET    | /models/{name}/-/versions/{v}/weights     | read  | safetensors + sha256     |
| POST   | /models/{name}/-/versions/{v}/archive     | write | archive                  |
| DELETE | /models/{name}/-/versions/{v}             | write | delete                   |
| PUT    | /models/{name}/-/aliases/{alias}          | write | set/move {"version": v}  |
| DELETE | /models/{name}/-/aliases/{alias}          | write | delete alias             |
| GET    | /resolve?ref=name@alias                   | read  | ref -> version           |
| GET    | /changes                                  | read  | change token (ETag, 304) |
| GET    | /events?since=&limit=                     | read  | change feed              |

Names keep their slashes in the path; `/-/` separates a name from its sub-resources (no name
contains a `-` segment). Errors: see `services.registry.errors`.
"""

from fastapi import APIRouter

from services.registry import models_routes, versions_routes

router = APIRouter(prefix="/v1/registry")
# The sub-resource routes go first: `/models/{name:path}` would also match `.../-/versions`.
router.include_router(versions_routes.router)
router.include_router(models_routes.router)

__all__ = ["router"]
