"""`PolicyServicer`: the gRPC face of the inference engine. It only translates (`convert`) and
maps errors (`errors`); the engine does the work, exactly as for the REST routes.

| rpc        | engine call                           | notes                                    |
|------------|---------------------------------------|------------------------------------------|
| `Act`      | `engine.act` with one row             | `state` + `ego_index` -> observation     |
| `ActBatch` | `engine.act` with B rows, or          | one vectorised pass; `observations`,     |
|            | `engine.act_columns` (COLUMNS format) | `states` or `observation_matrix`         |
| `ListEnvs` | `engine.envs()`                       |                                          |
| `Episode`  | `engine.act` per received step        | settings from the first message (or the  |
|            |                                       | latest that carried them); seed + t      |
|            | with an inferred partner: a           | the stream owns it (no store): beliefs   |
|            | `services.sessions.Session` per stream| updated from `observed`, then act; after |
|            |                                       | each answer `prepare_next` (ahead)       |

On the sync server each open `Episode` stream holds one worker thread until it ends, so the
streams are bounded (`episode_slots`): `episode_slots.total` of all clients (fewer than the
workers, so unary calls always have threads), `per_client` of one client, and a stream silent for
`episode_idle_s` seconds is ended with DEADLINE_EXCEEDED.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from functools import partial

import grpc
import numpy as np

from services.engine import ActRequest, ActResult, EngineError, InferenceEngine, InvalidRequest
from services.grpc_api import convert
from services.grpc_api.episode_slots import EpisodeSlots, steps_within
from services.grpc_api.errors import (
    StepError,
    check_parsed,
    translate_errors,
    translate_stream_errors,
)
from services.grpc_api.gen.coexist.v1 import policy_pb2 as pb
from services.grpc_api.gen.coexist.v1 import policy_pb2_grpc as pb_grpc
from services.sessions import Session


class PolicyServicer(pb_grpc.PolicyServiceServicer):
    """Implements `coexist.v1.PolicyService` over one shared `InferenceEngine`."""

    def __init__(
        self,
        engine: InferenceEngine,
        *,
        session_prefetch: bool = True,
        episode_slots: EpisodeSlots | None = None,
        episode_idle_s: float = 60.0,
    ) -> None:
        self.engine = engine
        self.session_prefetch = session_prefetch  # `Session.prepare_next` after each answer
        self.episode_slots = episode_slots or EpisodeSlots(4)  # open streams, shared and per client
        self.episode_idle_s = episode_idle_s  # a stream silent this long is ended

    def _run(
        self, message: convert.Row, build: Callable[[], ActRequest]
    ) -> tuple[ActRequest, list[ActResult]]:
        """Build the engine request of one row from `message` and act; errors blame the field
        the client sent (`observation` or `state`)."""
        from_state = convert.check_one_input(message)
        try:
            request = build()
            return request, self.engine.act(request)
        except EngineError as err:
            raise convert.renamed_for_transport(err, from_state=from_state) from None

    @translate_errors
    def Act(self, request: pb.ActRequest, context: grpc.ServicerContext) -> pb.ActResponse:
        act_request, results = self._run(request, partial(convert.act_request, request))
        return convert.act_response(act_request, results[0])

    @translate_errors
    def ActBatch(
        self, request: pb.ActBatchRequest, context: grpc.ServicerContext
    ) -> pb.ActBatchResponse:
        """Rows or columns (`format`); errors blame the input form the client sent."""
        if request.format not in (pb.BATCH_FORMAT_ROWS, pb.BATCH_FORMAT_COLUMNS):
            raise InvalidRequest(
                "format",
                f"expected BATCH_FORMAT_ROWS or BATCH_FORMAT_COLUMNS, got {request.format}",
            )
        source = convert.batch_source(request)
        try:
            act_request = convert.act_batch_request(request, source)
            if request.format == pb.BATCH_FORMAT_COLUMNS:
                columns = self.engine.act_columns(act_request)
                return convert.act_columns_response(act_request, columns)
            return convert.act_batch_response(act_request, self.engine.act(act_request))
        except EngineError as err:
            raise convert.renamed_for_batch(err, source) from None

    @translate_errors
    def ListEnvs(
        self, request: pb.ListEnvsRequest, context: grpc.ServicerContext
    ) -> pb.ListEnvsResponse:
        return pb.ListEnvsResponse(envs=[convert.env_info(e) for e in self.engine.envs()])

    @translate_stream_errors
    def Episode(
        self, requests: Iterator[pb.EpisodeStep], context: grpc.ServicerContext
    ) -> Iterator[pb.ActResponse]:
        with self.episode_slots.held(context.peer()):  # RESOURCE_EXHAUSTED beyond the bounds
            yield from self._episode(steps_within(requests, self.episode_idle_s))

    def _episode(self, requests: Iterator[pb.EpisodeStep]) -> Iterator[pb.ActResponse]:
        settings: pb.EpisodeSettings | None = None
        session: Session | None = None  # while a partner is inferred
        previous: tuple[str, np.ndarray] | None = None  # env, observation: for a later session
        budget: tuple[float, float, float] | None = None  # aail_budget's state, carried
        for t, step in enumerate(requests):
            try:
                check_parsed(step)
                if step.HasField("settings"):
                    settings = step.settings
                    session = self._episode_session(settings, session, t, previous, budget)
                if settings is None:
                    raise InvalidRequest(
                        "settings", "the first message of an episode must carry the settings"
                    )
                if session is not None:
                    response = self._session_step(session, step)
                else:
                    if step.observed:
                        raise InvalidRequest(
                            "observed[0].index",
                            "no partner of this episode is inferred: set infer on a partner "
                            "(or give it no goal) to send its actions",
                        )
                    build = partial(convert.episode_request, settings, step, t, budget)
                    act_request, results = self._run(step, build)
                    response = convert.act_response(act_request, results[0])
                    previous = (settings.env, act_request.observations[0])
                    first = results[0]
                    spent, total, value = first.budget_spent, first.budget_total, first.budget_value
                    budget = (
                        None
                        if spent is None or total is None or value is None
                        else (spent, total, value)
                    )
            except Exception as err:
                raise StepError(t, err) from err
            yield response
            if session is not None:  # the answer is sent: score the next step's evidence
                session.prepare_next()

    def _episode_session(
        self,
        settings: pb.EpisodeSettings,
        session: Session | None,
        t: int,
        previous: tuple[str, np.ndarray] | None,
        budget: tuple[float, float, float] | None = None,
    ) -> Session | None:
        """The stream's session under new settings: None when no partner is inferred; the same
        session with replaced settings (beliefs kept) or a new one starting at step t."""
        if not convert.infers_goals(settings):
            return None
        session_settings = convert.session_settings(settings)
        if session is not None:
            session.replace_settings(session_settings)
            return session
        # a session begun mid-stream judges the next step's `observed` on the last observation
        observation = previous[1] if previous and previous[0] == settings.env else None
        return Session(
            self.engine,
            session_settings,
            first_step=t,
            previous_observation=observation,
            prefetch=self.session_prefetch,
            budget_state=budget,
        )

    def _session_step(self, session: Session, step: pb.EpisodeStep) -> pb.ActResponse:
        """One step of an inferring episode; errors blame the field the client sent."""
        from_state = convert.check_one_input(step)
        try:
            observation, observed = convert.session_step_inputs(session.settings.env, step)
            answer = session.step(observation, observed)
        except EngineError as err:
            if from_state and err.field == "observation":
                raise err.renamed("state") from None
            raise convert.renamed_for_transport(err, from_state=from_state) from None
        return convert.session_response(session.settings, answer)
