"""The floors of `benchmarks/serving.py`: servers that do nothing but answer, with the settings
coexist serves with, so that a ratio against them shows what coexist adds per request.

Run: `.venv/bin/python benchmarks/floor_servers.py rest PORT` or `... grpc PORT`.

| floor  | what                                                                             |
|--------|----------------------------------------------------------------------------------|
| `rest` | a FastAPI app with one route, `GET /healthz` answering `{"status": "ok"}` as      |
|        | coexist's does, on uvicorn with uvloop and httptools, one worker, no access log   |
| `grpc` | grpcio's sync server on a pool of `GRPC_THREADS` threads with the standard health |
|        | servicer (`grpc_health.v1.health.HealthServicer`) set to SERVING and an           |
|        | act-shaped `coexist.v1.PolicyService/Act` (below)                                  |

The act-shaped method parses the request with the generated `ActRequest` class, as coexist does,
and answers one fixed `ActResponse` of the shape of coexist's answer to `benchmarks/serving.py`'s
act (five probabilities, four partner weights, five models with their sha256): as many bytes
in and out as a coexist act, no work between them. Its latency against the health check is what
the act's messages cost grpcio; coexist's act against it is what coexist's handler costs.
"""

from __future__ import annotations

import sys
from concurrent import futures
from typing import Any

GRPC_THREADS = 8  # as `services.settings.Settings.grpc_workers`


def rest_app() -> Any:
    from fastapi import FastAPI

    app = FastAPI()

    @app.get("/healthz")
    async def healthz() -> dict[str, str]:
        return {"status": "ok"}

    return app


def serve_rest(port: int) -> None:
    run_uvicorn(rest_app(), port)


def run_uvicorn(app: Any, port: int) -> None:
    """`app` on uvicorn with the settings `coexist serve` uses (loopback), until stopped."""
    import uvicorn

    uvicorn.run(
        app,
        host="127.0.0.1",
        port=port,
        workers=1,
        loop="uvloop",
        http="httptools",
        log_level="warning",
        access_log=False,
    )


def serve_grpc(port: int) -> None:
    import grpc
    from grpc_health.v1 import health, health_pb2, health_pb2_grpc

    server = grpc.server(futures.ThreadPoolExecutor(max_workers=GRPC_THREADS))
    servicer = health.HealthServicer()
    servicer.set("", health_pb2.HealthCheckResponse.SERVING)
    health_pb2_grpc.add_HealthServicer_to_server(servicer, server)
    server.add_generic_rpc_handlers((act_shaped_handlers(),))
    server.add_insecure_port(f"127.0.0.1:{port}")
    server.start()
    server.wait_for_termination()


def act_shaped_answer() -> Any:
    """An `ActResponse` of the shape of coexist's answer to a five-agent act (1 ego, 4 partners
    announced): the values are placeholders, the fields and their sizes are those of the real
    answer."""
    from envs.particle.scenarios import FIVE_AGENTS
    from services.grpc_api.gen.coexist.v1 import policy_pb2 as pb

    ego, partners = FIVE_AGENTS  # `benchmarks/serving.py`'s act
    goals = (ego, *partners)
    answer = pb.ActResponse(
        probs=[0.9741, 0.0041, 0.0032, 0.0107, 0.0079],
        action=0,
        greedy_action=0,
        action_meaning="rest",
        method="aail",
    )
    answer.diagnostics.task_entropy = 0.0337
    answer.diagnostics.task_weight = 0.7889
    for index in range(1, 5):
        answer.diagnostics.partner_weights.add(index=index, weight=0.25)
    for index, goal in enumerate(goals):
        role = "task" if index == 0 else "impact"
        model = answer.models.add(
            role=role,
            name=f"particle/{role}/{goal}",
            version=1,
            sha256=f"{index:x}" * 64,
            goal=goal,
        )
        if index:  # the partner an impact network serves
            model.partner_index = index
    return answer


def act_shaped_handlers() -> Any:
    """`coexist.v1.PolicyService/Act` answering `act_shaped_answer()` to every valid request."""
    import grpc

    from services.grpc_api.gen.coexist.v1 import policy_pb2 as pb

    answer = act_shaped_answer()
    act = grpc.unary_unary_rpc_method_handler(
        lambda request, context: answer,
        request_deserializer=pb.ActRequest.FromString,
        response_serializer=pb.ActResponse.SerializeToString,
    )
    return grpc.method_handlers_generic_handler("coexist.v1.PolicyService", {"Act": act})


if __name__ == "__main__":
    kind, port = sys.argv[1], int(sys.argv[2])
    {"rest": serve_rest, "grpc": serve_grpc}[kind](port)
