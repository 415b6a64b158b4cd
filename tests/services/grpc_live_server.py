"""A real gRPC server on 127.0.0.1 (a free port) over an engine of the tiny zoo, for the tests of
the gRPC transport, the SDK and the environment client (imported by them; not a test module)."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import grpc

from model_store.store import ModelStore
from services.engine import InferenceEngine
from services.grpc_api.gen.coexist.v1 import policy_pb2_grpc as pb_grpc
from services.grpc_api.server import GrpcServer, build_grpc_server

MAX_BATCH = 64  # small, so the oversized-batch error is cheap to provoke


@dataclass
class LiveServer:
    engine: InferenceEngine
    server: GrpcServer
    channel: grpc.Channel
    stub: pb_grpc.PolicyServiceStub

    @property
    def target(self) -> str:
        return f"127.0.0.1:{self.server.port}"


@contextmanager
def live_grpc_server(store: ModelStore, **server_kwargs: object) -> Iterator[LiveServer]:
    engine = InferenceEngine(store, max_batch=MAX_BATCH)
    server = build_grpc_server(engine, port=0, **server_kwargs)  # type: ignore[arg-type]
    server.start()
    channel = grpc.insecure_channel(f"127.0.0.1:{server.port}")
    try:
        yield LiveServer(engine, server, channel, pb_grpc.PolicyServiceStub(channel))
    finally:
        channel.close()
        server.stop(grace=None)
