#!/usr/bin/env bash
# The whole test suite, as CI runs it: start PostgreSQL (and Redis) when down, lint, type-check, test.
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=.venv/bin

if command -v pg_isready >/dev/null && ! pg_isready -q -h 127.0.0.1 -p 5432; then
  if command -v pg_ctlcluster >/dev/null; then
    pg_ctlcluster --skip-systemctl-redirect "$(ls /etc/postgresql)" main start || true
    for _ in $(seq 1 30); do pg_isready -q -h 127.0.0.1 -p 5432 && break; sleep 1; done
  fi
fi
# In CI the PostgreSQL tests must run, not skip.
if [ "${CI:-}" = "true" ]; then export COEXIST_REQUIRE_POSTGRES=1; fi
# Redis, for the shared session store's tests: started when installed and down (no disk writes)
if command -v redis-server >/dev/null; then
  if ! redis-cli -h 127.0.0.1 -p 6379 ping >/dev/null 2>&1; then
    redis-server --daemonize yes --bind 127.0.0.1 --port 6379 --save "" --appendonly no >/dev/null
    for _ in $(seq 1 30); do redis-cli -h 127.0.0.1 -p 6379 ping >/dev/null 2>&1 && break; sleep 0.2; done
  fi
  if [ "${CI:-}" = "true" ]; then export COEXIST_REQUIRE_REDIS=1; fi
fi

# The web console's browser tests drive Debian's Chromium (never a downloaded browser); they
# skip without it on a developer's machine and fail in CI.
if ! command -v chromium >/dev/null && command -v apt-get >/dev/null && [ "$(id -u)" = 0 ]; then
  export DEBIAN_FRONTEND=noninteractive
  (apt-get install -y -qq chromium >/dev/null 2>&1 \
    || { apt-get update -qq && apt-get install -y -qq chromium >/dev/null; }) \
    || echo "warning: could not install chromium; the browser tests will skip (and fail in CI)" >&2
fi

$BIN/ruff check .
$BIN/mypy .
$BIN/pytest -n 2 "$@"
