"""The inference REST API: `router` (POST /v1/act, POST /v1/act:batch, GET /v1/envs),
`sessions_router` (/v1/sessions: goals inferred online) and `install_error_handlers`. The app
must set `app.state.engine` to an `InferenceEngine` (and may set `app.state.sessions`)."""

from services.rest.act_api import router
from services.rest.errors import install_error_handlers
from services.rest.sessions_api import router as sessions_router

__all__ = ["install_error_handlers", "router", "sessions_router"]
