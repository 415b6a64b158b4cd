#!/usr/bin/env bash
# The whole test suite, as CI runs it: start PostgreSQL when it is down, lint, type-check, test.
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

$BIN/ruff check .
$BIN/mypy .
$BIN/pytest -n 2 "$@"
