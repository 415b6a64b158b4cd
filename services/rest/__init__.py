"""The inference REST API: `router` (POST /v1/act, POST /v1/act:batch, GET /v1/envs) and
`install_error_handlers`. The app must set `app.state.engine` to an `InferenceEngine`."""

from services.rest.act_api import router
from services.rest.errors import install_error_handlers

__all__ = ["install_error_handlers", "router"]
