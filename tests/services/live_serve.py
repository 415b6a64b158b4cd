"""One `coexist serve` process on loopback for the tests about the real server (body limits, the
event loop, tokens, TLS, restarts); imported by them, not a test module.

    with serving(tmp_path, store_url, COEXIST_MAX_BODY_BYTES="1048576") as server:
        httpx.post(f"{server.http_url}/v1/act", ...)

It builds on `replica_cluster` (`start_server`, `server_env`): the admin token is
`replica_cluster.ADMIN_TOKEN`, logs go to files in `log_dir`, and the server is stopped (SIGTERM,
then SIGKILL) on the way out. `zoo_copy` copies the tiny zoo's SQLite template (`conftest.py`) to
a private file, for module-scoped servers.
"""

from __future__ import annotations

import shutil
import ssl
import subprocess
import time
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path

import httpx
from replica_cluster import ADMIN_TOKEN, Server, server_env, start_server

AUTH = {"Authorization": f"Bearer {ADMIN_TOKEN}"}


def zoo_copy(template: Path, directory: Path) -> str:
    """A private copy of the tiny zoo's SQLite file in `directory`; its store URL."""
    directory.mkdir(parents=True, exist_ok=True)
    target = directory / "models.db"
    for suffix in ("", "-wal", "-shm"):
        source = Path(f"{template}{suffix}")
        if source.exists():
            shutil.copy(source, f"{target}{suffix}")
    return f"sqlite:///{target}"


def wait_until(
    server: Server, path: str, headers: Mapping[str, str], timeout: float, ca: Path | None = None
) -> None:
    """Poll `path` until it answers 200 (fail with the server's log tail if it exits); over
    HTTPS, trusting the authority `ca`, when given."""
    base = server.http_url.replace("http://", "https://") if ca else server.http_url
    verify = ssl.create_default_context(cafile=str(ca)) if ca else True
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if server.process.poll() is not None:
            raise AssertionError(f"server exited:\n{server.log_path.read_text()[-3000:]}")
        try:
            response = httpx.get(f"{base}{path}", headers=headers, timeout=1.0, verify=verify)
            if response.status_code == 200:
                return
        except httpx.TransportError:
            pass
        time.sleep(0.1)
    raise AssertionError(f"{path} never answered 200:\n{server.log_path.read_text()[-3000:]}")


@contextmanager
def serving(
    log_dir: Path,
    store_url: str,
    *,
    name: str = "serve",
    ready: bool = True,
    ca: Path | None = None,
    **env: str,
) -> Iterator[Server]:
    """`coexist serve --no-bootstrap` with `COEXIST_*` overrides `env`; waits for `/readyz`
    (with the admin token) or, with `ready=False` (an empty store), for `/healthz`; over HTTPS
    trusting the authority `ca` when the server speaks TLS."""
    server = start_server(name, server_env(store_url, log_dir, **env), log_dir)
    try:
        wait_until(server, "/readyz" if ready else "/healthz", AUTH, timeout=90.0, ca=ca)
        yield server
    finally:
        try:
            server.stop()
        except subprocess.TimeoutExpired:
            server.process.kill()
            server.process.wait()
