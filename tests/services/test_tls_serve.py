"""Transport security of a real `coexist serve` with `COEXIST_TLS_CERT_FILE` and
`COEXIST_TLS_KEY_FILE`: REST answers over HTTPS and gRPC over TLS, the SDK's clients reach both
given the authority's certificate (and a token: TLS and tokens together), and plaintext clients
are turned away. Settings that cannot work (one file of the pair) stop the server at start."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import httpx
import pytest
from coexist_client import CoexistClient, GrpcCoexistClient
from coexist_client.errors import Unavailable
from coexist_client.jobs import JobsClient
from live_serve import serving, zoo_copy
from replica_cluster import OBS
from tls_certs import make_tls_files

READ_TOKEN = "tls-read-token-0123456789"


def test_rest_and_grpc_speak_tls_and_the_sdk_follows(
    tmp_path: Path, _tiny_zoo_template: Path
) -> None:
    tls = make_tls_files(tmp_path / "tls")
    url = zoo_copy(_tiny_zoo_template, tmp_path / "store")
    env = {
        "COEXIST_TLS_CERT_FILE": str(tls.cert),
        "COEXIST_TLS_KEY_FILE": str(tls.key),
        "COEXIST_READ_TOKEN": READ_TOKEN,
    }
    with serving(tmp_path, url, ca=tls.ca, **env) as server:
        https = server.http_url.replace("http://", "https://")
        with (
            CoexistClient(https, token=READ_TOKEN, verify=tls.ca) as rest,
            GrpcCoexistClient(
                server.grpc_target, token=READ_TOKEN, root_certificates=tls.ca
            ) as secure,
            JobsClient(https, token=READ_TOKEN, verify=tls.ca) as jobs,
        ):
            a = rest.act("particle", "a2", OBS, partners={1: "b3"}, seed=3)
            b = secure.act("particle", "a2", OBS, partners={1: "b3"}, seed=3)
            assert a.probs == pytest.approx(b.probs) and a.models == b.models
            assert jobs.list() == []
        with pytest.raises(httpx.HTTPError):  # plain HTTP to the HTTPS port
            httpx.get(f"{server.http_url}/healthz", timeout=5)
        with pytest.raises(httpx.ConnectError):  # an authority the client does not trust
            httpx.get(f"{https}/healthz", timeout=5, verify=True)
        with (
            GrpcCoexistClient(server.grpc_target, token=READ_TOKEN, timeout=5) as plain,
            pytest.raises(Unavailable),
        ):
            plain.act("particle", "a2", OBS, partners={1: "b3"})


def test_half_a_tls_pair_stops_the_server(tmp_path: Path) -> None:
    tls = make_tls_files(tmp_path / "tls")
    env = {k: v for k, v in os.environ.items() if not k.startswith("COEXIST_")}
    env.update(
        COEXIST_DATA_DIR=str(tmp_path), COEXIST_DEV_MODE="1", COEXIST_TLS_CERT_FILE=str(tls.cert)
    )
    result = subprocess.run(
        [sys.executable, "-m", "cli.main", "serve", "--no-bootstrap"],
        env=env,
        capture_output=True,
        timeout=120,
    )
    assert result.returncode == 2, result.stderr.decode()[-2000:]
    assert b"COEXIST_TLS_CERT_FILE and COEXIST_TLS_KEY_FILE go together" in result.stderr
