"""The client distribution's shape: it imports nothing of the server, its version is the
repository's one version, and the four protocol-fixed client names are the one client."""

from __future__ import annotations

import ast
import tomllib
from pathlib import Path

import coexist_client
from coexist_client import (
    AsyncClient,
    AsyncCoexistClient,
    AsyncGrpcCoexistClient,
    Client,
    CoexistClient,
    GrpcCoexistClient,
)

REPO = Path(__file__).resolve().parents[2]
SERVER_PACKAGES = {"services", "model_store", "policy", "trainer", "envs", "evaluation", "cli"}
ALLOWED = {"coexist_client", "httpx", "grpc", "google", "numpy", "__future__"}


def _imports(path: Path) -> set[str]:
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names |= {alias.name.split(".")[0] for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module.split(".")[0])
    return names


def test_the_sdk_imports_only_its_dependencies_and_the_standard_library() -> None:
    import sys

    for path in sorted((REPO / "sdk" / "coexist_client").rglob("*.py")):
        third_party = {
            n for n in _imports(path) if n not in sys.stdlib_module_names and n not in ALLOWED
        }
        assert not third_party, f"{path}: imports {third_party}"
        assert not (_imports(path) & SERVER_PACKAGES), path


def test_one_version_source() -> None:
    version = (REPO / "VERSION").read_text().strip()
    assert coexist_client.__version__ == version
    sdk = tomllib.loads((REPO / "sdk" / "pyproject.toml").read_text())
    main = tomllib.loads((REPO / "pyproject.toml").read_text())
    for project in (sdk, main):
        assert "version" not in project["project"] and "version" in project["project"]["dynamic"]
    assert (REPO / "sdk" / "VERSION").resolve() == (REPO / "VERSION").resolve()
    deps = {d.split(">")[0].split("=")[0] for d in sdk["project"]["dependencies"]}
    assert deps == {"httpx", "grpcio", "protobuf", "numpy"}


def test_the_protocol_fixed_names_are_the_one_client() -> None:
    assert issubclass(CoexistClient, Client) and issubclass(GrpcCoexistClient, Client)
    assert issubclass(AsyncCoexistClient, AsyncClient)
    assert issubclass(AsyncGrpcCoexistClient, AsyncClient)
    assert CoexistClient("http://x").transport.grpc is False
    assert GrpcCoexistClient("x:1").transport.grpc is True
    assert Client("grpcs://x:1").transport.grpc is True
    assert Client("https://x").transport.grpc is False
    assert (REPO / "sdk" / "coexist_client" / "py.typed").exists()
