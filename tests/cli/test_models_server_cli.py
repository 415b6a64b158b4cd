"""`coexist models ... --server URL` against a real `coexist serve`: the registry commands through
the registry API (`cli.registry_remote`, token from the environment), the same answers as
through the database; and `coexist_client.RegistryClient`'s download checks the sha256."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest
from coexist_client import ChecksumMismatch, RegistryClient
from coexist_client.transport import HttpTransport
from console_zoo import build_console_zoo
from live_serve import serving
from replica_cluster import ADMIN_TOKEN, Server
from typer.testing import CliRunner, Result

from cli.main import app


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    folder = tmp_path_factory.mktemp("models_cli")
    with serving(folder, build_console_zoo(folder / "models.db")) as server:
        yield server


def _models(server: Server, *args: str, token: str | None = ADMIN_TOKEN) -> Result:
    env = {"COEXIST_ADMIN_TOKEN": token or "", "COLUMNS": "200"}
    return CliRunner().invoke(app, ["models", *args, "--server", server.http_url], env=env)


def test_list_and_show_through_the_server(server: Server) -> None:
    listed = _models(server, "list", "--env", "cooking", "--kind", "task")
    assert listed.exit_code == 0, listed.output
    assert "cooking/task/CarrotBanana" in listed.output and "particle/" not in listed.output
    shown = _models(server, "show", "particle/task/a2", "--version", "2")
    assert shown.exit_code == 0, shown.output
    assert "versions" in shown.output and "candidate" in shown.output
    assert '"lineage"' in shown.output


def test_promote_export_and_import_through_the_server(server: Server, tmp_path: Path) -> None:
    promoted = _models(server, "promote", "particle/impact/b3", "2", "--alias", "staging")
    assert promoted.exit_code == 0, promoted.output
    with RegistryClient(server.http_url, token=ADMIN_TOKEN) as registry:
        assert registry.resolve("particle/impact/b3@staging").version == 2
        before = len(registry.show("particle/impact/b3").versions)
    exported = _models(
        server, "export", "particle/impact/b3@production", "--out", str(tmp_path / "out")
    )
    assert exported.exit_code == 0, exported.output
    imported = _models(server, "import", str(tmp_path / "out"), "--alias", "imported")
    assert imported.exit_code == 0, imported.output
    with RegistryClient(server.http_url, token=ADMIN_TOKEN) as registry:
        model = registry.show("particle/impact/b3")
        assert len(model.versions) == before + 1
        new = model.aliases["imported"]
        data = registry.download("particle/impact/b3", new)
    assert data == (tmp_path / "out" / "weights.safetensors").read_bytes()


def test_a_write_without_the_token_fails_in_one_line(server: Server) -> None:
    refused = _models(server, "promote", "particle/task/a2", "1", token="wrong")
    assert refused.exit_code == 1
    assert "error:" in refused.output and "Traceback" not in refused.output


def test_exit_codes_through_the_server_are_the_databases(server: Server) -> None:
    missing = _models(server, "promote", "particle/task/a2", "99")  # not found: 1
    assert missing.exit_code == 1 and "error:" in missing.output
    invalid = _models(server, "promote", "particle/task/a2", "0")  # bad input: 2
    assert invalid.exit_code == 2 and "version" in invalid.output


def test_download_refuses_bytes_whose_sha256_differs(server: Server) -> None:
    def corrupt(request: httpx.Request) -> httpx.Response:
        with httpx.Client() as real:
            response = real.send(
                httpx.Request(request.method, str(request.url), headers=request.headers)
            )
        content = response.content
        if request.url.path.endswith("/weights"):
            content = content[:-1] + bytes([content[-1] ^ 1])
        return httpx.Response(response.status_code, headers=response.headers, content=content)

    registry = RegistryClient(server.http_url, token=ADMIN_TOKEN)
    registry.transport = HttpTransport(
        server.http_url, token=ADMIN_TOKEN, transport=httpx.MockTransport(corrupt)
    )
    with registry, pytest.raises(ChecksumMismatch):
        registry.download("particle/task/a2", 1)
