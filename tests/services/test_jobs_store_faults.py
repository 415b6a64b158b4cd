"""Faults that tell the truth: with the store's disk read-only or full, or its PostgreSQL
database dropped, a real `coexist serve` answers every jobs route with 503 (as the registry
does), never 500; and deleting a version an alias points at is refused with 409, as archiving
is, so the goal it serves stays served.

The disk faults need a filesystem of their own (a small tmpfs, remounted read-only or filled):
they skip where this process may not mount one (not root)."""

from __future__ import annotations

import os
import subprocess
import uuid
from collections.abc import Iterator
from pathlib import Path

import httpx
import psycopg
import pytest
from replica_cluster import (
    ADMIN_TOKEN,
    PG_URL,
    act_body,
    pg_schema_url,
    running,
    seed_zoo,
    server_env,
    start_server,
)
from sqlalchemy.engine import make_url

AUTH = {"Authorization": f"Bearer {ADMIN_TOKEN}"}
JOB = {"kind": "task", "goals": "a2", "steps": 20}


def _jobs_answers(base: str) -> dict[str, httpx.Response]:
    """Every jobs route once (a job id that does not exist where one is needed)."""
    missing = uuid.uuid4().hex
    return {
        "submit": httpx.post(f"{base}/v1/jobs", json=JOB, headers=AUTH, timeout=30),
        "list": httpx.get(f"{base}/v1/jobs", timeout=30),
        "get": httpx.get(f"{base}/v1/jobs/{missing}", timeout=30),
        "logs": httpx.get(f"{base}/v1/jobs/{missing}/logs", timeout=30),
        "cancel": httpx.delete(f"{base}/v1/jobs/{missing}", headers=AUTH, timeout=30),
    }


def _assert_all_503(answers: dict[str, httpx.Response]) -> None:
    statuses = {route: answer.status_code for route, answer in answers.items()}
    assert set(statuses.values()) == {503}, {r: a.text[:300] for r, a in answers.items()}
    for answer in answers.values():
        assert answer.json()["code"] == "store_unavailable", answer.text


@pytest.fixture
def own_disk(tmp_path: Path) -> Iterator[Path]:
    """A 16 MiB tmpfs mounted at `tmp_path/disk` (unmounted afterwards)."""
    disk = tmp_path / "disk"
    disk.mkdir()
    mounted = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=16M", "tmpfs", str(disk)], capture_output=True
    )
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {mounted.stderr.decode().strip()}")
    try:
        yield disk
    finally:
        subprocess.run(["umount", "-l", str(disk)], check=False)


def _fill(disk: Path) -> None:
    """Write to `disk` until not one byte more fits."""
    fd = os.open(disk / "filler", os.O_WRONLY | os.O_CREAT)
    try:
        for size in (1 << 16, 512, 1):
            try:
                while True:
                    os.write(fd, b"\0" * size)
            except OSError:
                pass
    finally:
        os.close(fd)


@pytest.mark.slow
def test_jobs_answer_503_when_the_disk_is_read_only_then_full(
    own_disk: Path, tmp_path: Path
) -> None:
    url = f"sqlite:///{own_disk / 'models.db'}"
    seed_zoo(url)
    server = start_server("disk", server_env(url, tmp_path / "data"), tmp_path)
    with running([server]):
        base = server.http_url
        assert httpx.get(f"{base}/v1/jobs").status_code == 200  # the table is open
        subprocess.run(["mount", "-o", "remount,ro", str(own_disk)], check=True)
        answers = _jobs_answers(base)
        # reads of a read-only database may still work; nothing may fail with a 500
        assert answers["submit"].status_code == 503, answers["submit"].text
        assert answers["cancel"].status_code in (404, 503), answers["cancel"].text
        assert all(a.status_code in (200, 404, 503) for a in answers.values()), answers

        subprocess.run(["mount", "-o", "remount,rw", str(own_disk)], check=True)
        _fill(own_disk)
        answers = _jobs_answers(base)
        assert answers["submit"].status_code == 503, answers["submit"].text
        assert "disk" in answers["submit"].json()["detail"]
        assert all(a.status_code in (200, 404, 503) for a in answers.values()), answers
        (own_disk / "filler").unlink()  # room again: the same server recovers
        assert httpx.get(f"{base}/v1/jobs").json() == {"jobs": []}  # nothing half-written


@pytest.mark.postgres
@pytest.mark.slow
def test_jobs_answer_503_when_the_database_is_dropped(tmp_path: Path) -> None:
    name = f"coexist_dropped_{uuid.uuid4().hex[:10]}"
    try:
        with psycopg.connect(PG_URL, autocommit=True, connect_timeout=3) as conn:
            conn.execute(f'CREATE DATABASE "{name}"')
    except psycopg.Error as exc:
        if os.environ.get("COEXIST_REQUIRE_POSTGRES"):
            pytest.fail(f"PostgreSQL not reachable at {PG_URL}: {exc}")
        pytest.skip(f"PostgreSQL not reachable at {PG_URL}: {exc}")
    url = make_url(PG_URL).set(database=name).render_as_string(hide_password=False)
    try:
        seed_zoo(url)
        server = start_server("dropped", server_env(url, tmp_path / "data"), tmp_path)
        with running([server]):
            base = server.http_url
            assert httpx.get(f"{base}/v1/jobs").status_code == 200
            with psycopg.connect(PG_URL, autocommit=True) as conn:
                conn.execute(f'DROP DATABASE "{name}" WITH (FORCE)')
            _assert_all_503(_jobs_answers(base))
            registry = httpx.get(f"{base}/v1/registry/models", timeout=30)
            assert registry.status_code == 503  # as the registry answers
    finally:
        with psycopg.connect(PG_URL, autocommit=True) as conn:
            conn.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')


@pytest.mark.postgres
@pytest.mark.slow
def test_deleting_the_version_production_serves_is_refused(tmp_path: Path) -> None:
    with pg_schema_url() as url:
        seed_zoo(url)  # particle/task/a2: version 1 at production, version 2 at latest
        server = start_server("delete", server_env(url, tmp_path / "data"), tmp_path)
        with running([server]):
            base = server.http_url
            versions = f"{base}/v1/registry/models/particle/task/a2/-/versions"
            for version, alias in ((1, "production"), (2, "latest")):
                refused = httpx.delete(f"{versions}/{version}", headers=AUTH)
                assert refused.status_code == 409, refused.text
                error = refused.json()
                assert error["field"] == "version" and alias in error["detail"]
            model = httpx.get(f"{base}/v1/registry/models/particle/task/a2").json()
            assert model["aliases"] == {"production": 1, "latest": 2}
            served = httpx.post(f"{base}/v1/act", json=act_body())
            assert served.status_code == 200, served.text
            assert httpx.get(f"{base}/readyz").status_code == 200
            alias = f"{base}/v1/registry/models/particle/task/a2/-/aliases/latest"
            assert httpx.put(alias, json={"version": 1}, headers=AUTH).status_code == 200
            assert httpx.delete(f"{versions}/2", headers=AUTH).status_code == 204
