"""The shared session stores' servers for the tests (imported by them; not a test module): a
Redis URL and a fresh PostgreSQL schema, each skipped (or failed, under COEXIST_REQUIRE_REDIS /
COEXIST_REQUIRE_POSTGRES) when no server answers, and a secret of the test's own, so that each
test's sessions live in a namespace of their own.

    with shared_store_url("redis") as url: ...          # or "postgres"
    codec = SessionCodec(new_secret())
"""

from __future__ import annotations

import os
import secrets
from collections.abc import Iterator
from contextlib import contextmanager

import pytest
from replica_cluster import pg_schema_url

REDIS_URL = os.environ.get("COEXIST_TEST_REDIS_URL", "redis://127.0.0.1:6379/0")
# parameters of a test over both stores
BACKENDS = (
    pytest.param("redis", marks=pytest.mark.redis),
    pytest.param("postgres", marks=pytest.mark.postgres),
)


def new_secret() -> bytes:
    return secrets.token_hex(16).encode()


@contextmanager
def redis_url() -> Iterator[str]:
    """`REDIS_URL` once a PING answers; afterwards every key a test's namespace left is gone
    (the tests' namespaces start with `coexist:`; each test removes its own)."""
    import redis

    client = redis.Redis.from_url(REDIS_URL, socket_connect_timeout=2)
    try:
        client.ping()
    except redis.RedisError as exc:
        if os.environ.get("COEXIST_REQUIRE_REDIS"):
            pytest.fail(f"Redis not reachable at {REDIS_URL}: {exc}")
        pytest.skip(f"Redis not reachable at {REDIS_URL}: {exc}")
    finally:
        client.close()
    yield REDIS_URL


def drop_namespace(url: str, namespace: str) -> None:
    """Remove the keys of one namespace (Redis; a PostgreSQL schema is dropped whole)."""
    if not url.startswith("redis"):
        return
    import redis

    with redis.Redis.from_url(url) as client:
        keys = list(client.scan_iter(f"coexist:{namespace}:*"))
        if keys:
            client.delete(*keys)


@contextmanager
def shared_store_url(kind: str) -> Iterator[str]:
    if kind == "redis":
        with redis_url() as url:
            yield url
    else:
        with pg_schema_url() as url:
            yield url
