"""One address parser for the SDK and the `coexist` command line (`coexist_client.address`):
every written form, the protocol a bare `host:port` takes, and bad addresses as a `ValueError`
that says what was expected (never a retryable `Unavailable`)."""

from __future__ import annotations

import pytest
from coexist_client import Client, CoexistClient, GrpcCoexistClient, RegistryClient
from coexist_client.address import ServerAddress, parse_address
from coexist_client.jobs import JobsClient
from typer.testing import CliRunner

from cli.main import app as coexist

FORMS = [
    ("http://127.0.0.1:8000", None, ServerAddress("http", False, "http://127.0.0.1:8000")),
    ("http://127.0.0.1:8000/", None, ServerAddress("http", False, "http://127.0.0.1:8000")),
    (
        "HTTPS://policy.example/api/",
        None,
        ServerAddress("http", True, "https://policy.example/api"),
    ),
    ("grpc://127.0.0.1:50051", None, ServerAddress("grpc", False, "127.0.0.1:50051")),
    ("grpcs://policy.example:443/", None, ServerAddress("grpc", True, "policy.example:443")),
    ("unix:///run/coexist.sock", None, ServerAddress("grpc", False, "unix:///run/coexist.sock")),
    ("localhost:8000", None, ServerAddress("http", False, "http://localhost:8000")),
    ("localhost:8000", "http", ServerAddress("http", False, "http://localhost:8000")),
    ("localhost:50051", "grpc", ServerAddress("grpc", False, "localhost:50051")),
    ("[::1]:50051", "grpc", ServerAddress("grpc", False, "[::1]:50051")),
    (" policy.example ", None, ServerAddress("http", False, "http://policy.example")),
]


@pytest.mark.parametrize(("text", "protocol", "expected"), FORMS)
def test_every_written_form(text: str, protocol: str | None, expected: ServerAddress) -> None:
    assert parse_address(text, protocol) == expected  # type: ignore[arg-type]


BAD = [
    ("", "empty"),
    ("ftp://host:21", "unknown scheme 'ftp://'"),
    ("localhost:http", "expected http(s)://host[:port]"),
    ("localhost:99999", "out of range"),
    ("grpc://host", "a gRPC address needs a port"),
    ("grpc://host:1/v1", "a gRPC address has no path"),
    ("http://", "expected http(s)://host[:port]"),
    ("unix:", "a unix socket needs a path"),
]


@pytest.mark.parametrize(("text", "message"), BAD)
def test_bad_addresses_are_value_errors_saying_what_was_expected(text: str, message: str) -> None:
    with pytest.raises(ValueError, match="server address") as err:
        parse_address(text)
    assert message in str(err.value)


def test_a_client_of_one_protocol_refuses_the_other_s_address() -> None:
    with pytest.raises(ValueError, match="is a grpc address, but this client speaks REST"):
        RegistryClient("grpc://127.0.0.1:50051")
    with pytest.raises(ValueError, match="is a grpc address, but this client speaks REST"):
        JobsClient("grpcs://127.0.0.1:50051")
    with pytest.raises(ValueError, match="is a grpc address, but this client speaks REST"):
        CoexistClient("grpc://127.0.0.1:50051")
    with pytest.raises(ValueError, match="is a http address, but this client speaks gRPC"):
        GrpcCoexistClient("http://127.0.0.1:8000")
    with pytest.raises(ValueError, match="unknown scheme"):
        RegistryClient("htp://127.0.0.1:8000")


def test_the_client_and_the_command_line_read_a_bare_address_alike() -> None:
    with Client("localhost:8000") as client:
        assert not client.transport.grpc  # REST, as `coexist run --server localhost:8000`
    with Client("localhost:50051", protocol="grpc") as client:
        assert client.transport.grpc
    refused = CliRunner().invoke(
        coexist, ["run", "--server", "ftp://localhost:8000"], env={"COLUMNS": "300"}
    )
    assert refused.exit_code == 2 and "unknown scheme 'ftp://'" in refused.output
