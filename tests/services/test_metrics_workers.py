"""`/metrics` of a real `coexist serve --workers 2`: requests spread over both workers, and every
scrape, whichever worker answers it, counts all of them (prometheus_client's multiprocess mode,
its directory emptied at start: `services.metrics.prepare_multiprocess_dir`)."""

from __future__ import annotations

import re
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import grpc
import httpx
import pytest
from live_serve import AUTH, wait_until, zoo_copy
from replica_cluster import server_env, start_server

from services.grpc_api.gen.coexist.v1 import policy_pb2 as pb
from services.grpc_api.gen.coexist.v1 import policy_pb2_grpc as pb_grpc

OBS = [0.1, 0.4, 0.0, 0.0, 0.7, 0.6, 0.0, 0.0]
ACT_BODY = {
    "env": "particle",
    "ego_goal": "a2",
    "observation": OBS,
    "partners": [{"index": 1, "goal": "b3"}],
}
HTTP_SAMPLE = 'coexist_http_requests_total{method="POST",route="/v1/act",status="200"}'
GRPC_SAMPLE = 'coexist_grpc_requests_total{code="OK",method="/coexist.v1.PolicyService/Act"}'


def _count(metrics: str, sample: str) -> float:
    found = re.search(rf"^{re.escape(sample)} ([0-9.e+]+)$", metrics, re.MULTILINE)
    return float(found.group(1)) if found else 0.0


def _act_on_new_connections(base: str, n: int) -> None:
    """`n` acts, each on its own connection, 8 at a time: the workers accept side by side."""

    def one(_: int) -> None:
        with httpx.Client(base_url=base, timeout=30) as client:
            assert client.post("/v1/act", json=ACT_BODY).status_code == 200

    with ThreadPoolExecutor(8) as pool:
        list(pool.map(one, range(n)))


@pytest.mark.slow
def test_a_scrape_counts_the_requests_of_every_worker(
    _tiny_zoo_template: Path, tmp_path: Path
) -> None:
    store = zoo_copy(_tiny_zoo_template, tmp_path / "store")
    multiproc = tmp_path / "data" / "prometheus"
    multiproc.mkdir(parents=True)
    (multiproc / "counter_999999.db").write_bytes(b"stale")  # an earlier run's: emptied at start
    env = server_env(store, tmp_path / "data")
    server = start_server("workers", env, tmp_path, ("serve", "--no-bootstrap", "--workers", "2"))
    try:
        wait_until(server, "/readyz", AUTH, timeout=90.0)
        sent = 0
        while sent < 400 and len(list(multiproc.glob("counter_*.db"))) < 2:
            _act_on_new_connections(server.http_url, 40)
            sent += 40
        writers = {path.name for path in multiproc.glob("counter_*.db")}
        assert len(writers) >= 2, f"all {sent} requests went to one worker: {writers}"
        assert "counter_999999.db" not in writers
        with grpc.insecure_channel(server.grpc_target) as channel:
            stub = pb_grpc.PolicyServiceStub(channel)
            request = pb.ActRequest(
                env="particle",
                ego_goal="a2",
                observation=OBS,
                partners=[pb.PartnerSpec(index=1, goal="b3")],
            )
            for _ in range(5):
                stub.Act(request, timeout=30)
        for _ in range(6):  # new connections: scrapes answered by either worker
            metrics = httpx.get(f"{server.http_url}/metrics", timeout=30).text
            assert _count(metrics, HTTP_SAMPLE) == sent
            assert _count(metrics, GRPC_SAMPLE) == 5
    finally:
        server.stop()
