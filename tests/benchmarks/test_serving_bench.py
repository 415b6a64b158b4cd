"""benchmarks/serving.py: its parsers of wrk / h2load output, its verdicts, its payloads, and one
short real run when wrk and h2load are installed (the figures themselves are not asserted)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))

import serving  # noqa: E402

WRK_OUT = """Running 3s test @ http://127.0.0.1:8000/v1/act
  1 threads and 32 connections
  Latency Distribution
     50%  312.00us
     75%  400.00us
  9000 requests in 3.01s, 2.73MB read
  Socket errors: connect 0, read 1, write 0, timeout 2
  Non-2xx or 3xx responses: 4
Requests/sec:   2990.03
"""

H2LOAD_OUT = """finished in 3.00s, 1212.00 req/s, 340KB/s
requests: 3636 total, 3637 started, 3636 done, 3630 succeeded, 5 failed, 1 errored, 0 timeout
"""


def test_wrk_output_is_parsed_with_units_and_failures() -> None:
    requests, seconds, p50_ms, failed = serving.parse_wrk(WRK_OUT)
    assert (requests, seconds, failed) == (9000, 3.01, 3 + 4)
    assert p50_ms == pytest.approx(0.312)
    assert serving.parse_wrk(WRK_OUT.replace("312.00us", "1.50ms"))[2] == pytest.approx(1.5)


def test_h2load_output_and_log_give_the_median_latency() -> None:
    log = "".join(f"1700000000{i}\t200\t{us}\n" for i, us in enumerate([100, 900, 300]))
    requests, seconds, p50_ms, failed = serving.parse_h2load(H2LOAD_OUT, log)
    assert (requests, seconds, failed) == (3630, 3.0, 6)
    assert p50_ms == pytest.approx(0.3)


def test_unexpected_output_is_an_error_not_a_zero() -> None:
    with pytest.raises(ValueError, match="wrk"):
        serving.parse_wrk("connection refused")
    with pytest.raises(ValueError, match="h2load"):
        serving.parse_h2load(H2LOAD_OUT, "")


def _case(transport: str, case: str, c: int, requests: int, p50: float, rows: int = 1):
    return serving.Case(transport, case, c, requests, 1.0, p50, rows, 0)


def test_verdicts_compare_each_transport_with_its_own_floor() -> None:
    cases = []
    for t, slow in (("REST", 1.0), ("gRPC", 3.0)):
        cases += [
            _case(t, "no-op", 1, 5000, 0.2),
            _case(t, "no-op", 32, 10000, 3.0),
            _case(t, "act", 1, 3000, 0.2 * slow * 1.5),
            _case(t, "act", 32, 3000, 9.0),
            _case(t, "batch", 1, 400, 2.5, rows=256),
        ]
    got = {name: (round(value, 2), met) for name, value, _, met in serving.verdicts(cases)}
    assert got["REST: act p50 / no-op p50 (c=1)"] == (1.5, True)
    assert got["gRPC: act p50 / no-op p50 (c=1)"] == (4.5, False)
    assert got["REST: act req/s / no-op req/s (c=32)"] == (0.3, False)
    assert got["REST: batch actions/s / act req/s (c=1)"] == (34.13, True)


def test_verdicts_against_the_bare_servers() -> None:
    cases = []
    for t in ("REST", "gRPC"):
        cases += [
            _case(t, "no-op", 1, 5000, 0.22),
            _case(t, "no-op", 32, 10000, 3.0),
            _case(t, "act", 1, 3000, 0.3),
            _case(t, "act", 32, 3000, 9.0),
            _case(t, "batch", 1, 400, 2.5, rows=256),
            _case(t, "floor no-op", 1, 6000, 0.2),
            _case(t, "floor no-op", 32, 8000, 3.0),
        ]
    got = {name: (round(value, 2), met) for name, value, _, met in serving.verdicts(cases)}
    assert got["REST: no-op p50 / bare FastAPI no-op p50 (c=1)"] == (1.1, True)
    assert got["REST: act p50 / bare FastAPI no-op p50 (c=1)"] == (1.5, True)
    assert got["gRPC: health p50 / bare grpcio health p50 (c=1)"] == (1.1, True)
    assert got["gRPC: act p50 / bare grpcio health p50 (c=1)"] == (1.5, True)
    assert got["REST: act req/s / bare FastAPI no-op req/s (c=32)"] == (0.38, False)
    assert len(got) == 11
    slower = [
        c if c.case != "no-op" else _case(c.transport, "no-op", c.concurrency, 1, 0.24)
        for c in cases
    ]
    got = {name: met for name, _, _, met in serving.verdicts(slower)}
    assert not got["REST: no-op p50 / bare FastAPI no-op p50 (c=1)"]
    assert not got["gRPC: health p50 / bare grpcio health p50 (c=1)"]


def test_the_act_shaped_floor_splits_the_grpc_act() -> None:
    cases = [_case("gRPC", "act", 1, 2000, 0.5), _case("gRPC", "floor act", 1, 5000, 0.2)]
    floor, handler = serving.handler_share(cases)
    assert (floor, round(handler, 6)) == (0.2, 0.3)
    assert serving.handler_share(cases[:1]) is None  # no floor measured: nothing to split


def test_the_act_shaped_answer_has_the_fields_of_a_five_agent_answer() -> None:
    import floor_servers

    answer = floor_servers.act_shaped_answer()
    assert len(answer.probs) == 5 and len(answer.diagnostics.partner_weights) == 4
    assert [m.role for m in answer.models] == ["task"] + ["impact"] * 4
    assert all(len(m.sha256) == 64 and m.goal for m in answer.models)
    assert [m.partner_index for m in answer.models[1:]] == [1, 2, 3, 4]


def test_rounds_give_median_figures_and_median_ratios() -> None:
    def one_round(act_p50: float, noop_rps: int, act_rps: int) -> list:
        return (
            [_case(t, "no-op", c, noop_rps, 0.2) for t in ("REST", "gRPC") for c in (1, 32)]
            + [_case(t, "act", c, act_rps, act_p50) for t in ("REST", "gRPC") for c in (1, 32)]
            + [_case(t, "batch", 1, 100, 3.0, rows=256) for t in ("REST", "gRPC")]
        )

    # a target is the median of the rounds' ratios (c=32: 0.45), not the ratio of medians (0.5)
    rounds = [one_round(0.3, 1000, 400), one_round(0.5, 2000, 900), one_round(0.7, 1000, 500)]
    medians = {(c.transport, c.case, c.concurrency): c for c in serving.median_cases(rounds)}
    assert medians["REST", "act", 1].p50_ms == 0.5 and medians["REST", "act", 1].rps == 500
    got = {name: (round(value, 2), met) for name, value, _, met in serving.median_verdicts(rounds)}
    assert got["REST: act p50 / no-op p50 (c=1)"] == (2.5, False)
    assert got["REST: act req/s / no-op req/s (c=32)"] == (0.45, True)


def test_payloads_are_the_five_agent_scenario() -> None:
    from services.grpc_api.gen.coexist.v1 import policy_pb2 as pb

    act = json.loads(serving.rest_bodies()["act"])
    assert act["ego_goal"] == serving.EGO and len(act["partners"]) == 4
    assert len(act["observation"]) == 20
    batch = json.loads(serving.rest_bodies()["batch"])
    assert len(batch["observations"]) == serving.BATCH and batch["format"] == "columns"
    rows = json.loads(serving.rest_bodies()["batch rows"])
    assert rows["observations"] == batch["observations"] and "format" not in rows
    framed = serving.grpc_bodies()["act"]
    assert framed[0] == 0 and int.from_bytes(framed[1:5], "big") == len(framed) - 5
    grpc_batch = pb.ActBatchRequest.FromString(serving.grpc_bodies()["batch"][5:])
    assert grpc_batch.format == pb.BATCH_FORMAT_COLUMNS and not grpc_batch.observations
    assert (grpc_batch.observation_matrix.rows, grpc_batch.observation_matrix.cols) == (256, 20)
    grpc_rows = pb.ActBatchRequest.FromString(serving.grpc_bodies()["batch rows"][5:])
    assert grpc_rows.format == pb.BATCH_FORMAT_ROWS and len(grpc_rows.observations) == 256
    assert list(grpc_rows.observations[3].values) == list(
        grpc_batch.observation_matrix.values[60:80]
    )


@pytest.mark.slow
@pytest.mark.skipif(
    shutil.which("wrk") is None
    or shutil.which("h2load") is None
    or shutil.which("taskset") is None,
    reason="wrk / h2load not installed (apt-get install wrk nghttp2-client)",
)
def test_a_short_real_run_answers_every_request(tmp_path: Path) -> None:
    out = tmp_path / "serving.json"
    subprocess.run(
        [
            sys.executable,
            str(ROOT / "benchmarks/serving.py"),
            "--duration",
            "1",
            "--json",
            str(out),
        ],
        check=True,
        timeout=300,
        cwd=ROOT,
    )
    figures = json.loads(out.read_text())
    # 16 of coexist (batch rows and act default: c = 1) and 5 of the bare servers (the
    # act-shaped floor at c = 1); 6 + 5 targets
    assert len(figures["cases"]) == 21 and len(figures["targets"]) == 11
    assert {c["case"] for c in figures["cases"]} == {
        "no-op",
        "act",
        "batch",
        "batch rows",
        "act default",
        "floor no-op",
        "floor act",
    }
    assert all(c["failed"] == 0 and c["requests"] > 0 for c in figures["cases"])
