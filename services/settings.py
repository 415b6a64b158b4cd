"""Settings of coexist, from `COEXIST_*` environment variables: the one table of them all.

The servers read one pydantic-settings class (`Settings`, the rows marked *server*); the CLI's
store commands read the two store rows directly (`model_store.defaults`); the last rows are read
by the test suite and by Ray.

| variable                      | default            | read by       | meaning                                           |
|-------------------------------|--------------------|---------------|---------------------------------------------------|
| `COEXIST_STORE_URL`           | SQLite in data dir | server, CLI   | model store URL (`sqlite:///…`, `postgresql://…`) |
| `COEXIST_DATA_DIR`            | `.coexist`         | server, CLI   | where the SQLite file (and bootstrap run) lives   |
| `COEXIST_CREATE_STORE`        | false              | server        | a `STORE_URL` SQLite file that does not exist is  |
|                               |                    |               | created (`serve --create-store`); otherwise the   |
|                               |                    |               | server refuses to start, naming the path (the     |
|                               |                    |               | default file in `DATA_DIR` is always created)     |
| `COEXIST_ADMIN_TOKEN`         | `dev-token`        | server, CLI   | bearer token for registry and job writes (the     |
|                               |                    |               | `coexist jobs` CLI sends it); unless `DEV_MODE`,  |
|                               |                    |               | refused at its default and when weak (under 16    |
|                               |                    |               | characters, whitespace, under 8 distinct ones;    |
|                               |                    |               | the read token too)                               |
| `COEXIST_READ_TOKEN`          | unset              | server        | bearer token for reads (inference included); with |
|                               |                    |               | reads open a request without a token is served    |
|                               |                    |               | and one with a wrong token refused (403)          |
| `COEXIST_REQUIRE_READ_TOKEN`  | false              | server        | every route but `/healthz` (and gRPC health)      |
|                               |                    |               | needs the read or admin token (`services.auth`)   |
| `COEXIST_DEV_MODE`            | false              | server        | allow the default admin token (and weak tokens)   |
| `COEXIST_MAX_ARTIFACT_BYTES`  | 64 MiB             | server        | upload size limit                                 |
| `COEXIST_MAX_BODY_BYTES`      | 16 MiB             | server        | JSON request bodies: larger ones are refused      |
|                               |                    |               | (413) before they are read; fits a batch of       |
|                               |                    |               | `MAX_BATCH` rows of 208 numbers at full precision |
| `COEXIST_HOST`                | `127.0.0.1`        | server        | address to listen on (`0.0.0.0` in a container)   |
| `COEXIST_ALLOWED_HOSTS`       | loopback names     | `serve`       | `Host` names REST answers (comma-separated, `*.`  |
|                               |                    |               | for subdomains, `*`: any); others get 400. Unset: |
|                               |                    |               | `localhost`, `127.0.0.1`, `::1` on a loopback     |
|                               |                    |               | `HOST`, any otherwise (`services.allowed_hosts`)  |
| `COEXIST_HTTP_PORT`           | 8000               | server        | REST port                                         |
| `COEXIST_TLS_CERT_FILE`,      | unset              | server        | PEM certificate (chain) and private key: REST     |
| `COEXIST_TLS_KEY_FILE`        |                    |               | serves HTTPS and gRPC TLS on their ports (both or |
|                               |                    |               | neither; docs/security.md)                        |
| `COEXIST_GRPC_PORT`           | 50051              | server        | gRPC port (0: any free port)                      |
| `COEXIST_GRPC_ENABLED`        | true               | server        | serve gRPC beside REST                            |
| `COEXIST_GRPC_WORKERS`        | 8                  | server        | gRPC thread pool size (at least 2; health Check   |
|                               |                    |               | has 2 threads of its own besides)                 |
| `COEXIST_MAX_EPISODES`        | half the workers   | server        | open gRPC `Episode` streams (and health `Watch`   |
|                               |                    |               | streams) of all clients together; each holds a    |
|                               |                    |               | worker thread, so it must be fewer than           |
|                               |                    |               | `GRPC_WORKERS`: unary calls always find one       |
| `COEXIST_MAX_EPISODES_PER_CLIENT` | `MAX_EPISODES` | server        | open gRPC `Episode` streams of one client address |
|                               |                    |               | (behind a proxy every client has its address)     |
| `COEXIST_EPISODE_IDLE_TIMEOUT_S` | 60              | server        | an `Episode` stream that sent no step this long   |
|                               |                    |               | is ended with DEADLINE_EXCEEDED                   |
| `COEXIST_HTTP_MAX_HEADER_BYTES` | 65536          | server        | request line and headers of one HTTP request:     |
|                               |                    |               | larger ones get 431 (`services.http_protocol`)    |
| `COEXIST_HTTP_HEADER_TIMEOUT_S` | 10               | server        | time a connection has to send a request's line    |
|                               |                    |               | and headers, from its opening or the previous     |
|                               |                    |               | answer; then it is closed (408)                   |
| `COEXIST_HTTP_IDLE_TIMEOUT_S` | 30                 | server        | silence allowed while a request body is due, and  |
|                               |                    |               | while an answer waits for its client to read it   |
| `COEXIST_HTTP_KEEP_ALIVE_S`   | 5                  | server        | an idle keep-alive connection is closed after it  |
| `COEXIST_MAX_CONNECTIONS`     | fd limit - 256     | server        | open HTTP connections per process (at most the    |
|                               |                    |               | file-descriptor limit less 256); past it the      |
|                               |                    |               | longest-waiting idle one is closed, else 503      |
|                               |                    |               | (docs/operations.md)                              |
| `COEXIST_REFRESH_INTERVAL_S`  | 2.0                | server        | how often aliases are re-checked (hot reload)     |
| `COEXIST_CACHE_SIZE`          | 256                | server        | networks kept loaded (LRU)                        |
| `COEXIST_MAX_BATCH`           | 4096               | server        | rows allowed in one act:batch                     |
| `COEXIST_SESSION_TTL_S`       | 300                | server        | a REST session idle this long is forgotten        |
| `COEXIST_MAX_SESSIONS`        | 1000               | server        | live REST sessions per server process             |
| `COEXIST_MAX_SESSIONS_PER_CLIENT` | 100            | server        | live REST sessions one client (by address) may    |
|                               |                    |               | hold; behind a proxy set `FORWARDED_ALLOW_IPS` to |
|                               |                    |               | it, else every client shares the proxy's address  |
| `COEXIST_FORWARDED_ALLOW_IPS` | unset (none)       | `serve`       | proxies whose `X-Forwarded-For` and               |
|                               |                    |               | `X-Forwarded-Proto` are believed (comma-separated |
|                               |                    |               | addresses or networks, `*` for any); unset: the   |
|                               |                    |               | client is the connection's address, whatever a    |
|                               |                    |               | header says (uvicorn's own default, which         |
|                               |                    |               | believes 127.0.0.1, is not used)                  |
| `COEXIST_SESSION_PREFETCH`    | true               | server        | after a session step's answer is sent, score the  |
|                               |                    |               | next step's evidence ahead (REST and `Episode`;   |
|                               |                    |               | `services.sessions.session`, "Scoring ahead")     |
| `COEXIST_SESSION_STORE_URL`   | unset (in memory)  | server        | REST sessions kept in Redis (`redis://…`) or      |
|                               |                    |               | PostgreSQL (`postgresql://…`), so every worker    |
|                               |                    |               | and replica serves every session                  |
|                               |                    |               | (`services.sessions.shared`); unset: in this      |
|                               |                    |               | process's memory                                  |
| `COEXIST_SESSION_SECRET`      | unset              | server        | required with `SESSION_STORE_URL`, the same on    |
|                               |                    |               | every replica of a deployment: signs session ids  |
|                               |                    |               | and stored session state; never logged            |
| `COEXIST_WORKERS`             | 1                  | server        | uvicorn worker processes (set by `coexist serve   |
|                               |                    |               | --workers`); > 1 refuses REST sessions unless     |
|                               |                    |               | `SESSION_STORE_URL` is set                        |
| `COEXIST_DIRECT_JSON`         | true               | server        | a valid JSON act or session body goes straight to |
|                               |                    |               | its endpoint (`services.rest.direct_route`); off: |
|                               |                    |               | FastAPI's router answers every request (the same  |
|                               |                    |               | answers, more CPU per act: docs/performance.md)   |
| `COEXIST_LOG_FORMAT`          | `text`             | server        | `json`: one JSON object per line (the images set  |
|                               |                    |               | it); `text`: for a terminal (`services.logging`)  |
| `COEXIST_LOG_LEVEL`           | `info`             | server        | `debug` (also probe access lines), `info`,        |
|                               |                    |               | `warning`, `error`                                |
| `COEXIST_JOB_LEASE_S`         | 30                 | server        | a running training job's lease: renewed every     |
|                               |                    |               | sixth of it; a job whose lease ran out is resumed |
|                               |                    |               | by another (or the restarted) server, and a       |
|                               |                    |               | runner that could not renew it stops its trainer  |
| `COEXIST_JOBS_URL`            | see meaning        | server        | the SQL database of the training jobs' table      |
|                               |                    |               | (`sqlite:///…`, `postgresql://…`; a secret: never |
|                               |                    |               | shown); unset: the model store's database when it |
|                               |                    |               | is SQL, else `sqlite:///{DATA_DIR}/jobs.db`       |
| `COEXIST_SHUTDOWN_GRACE_S`    | 10                 | server        | on SIGTERM: how long in-flight HTTP requests and  |
|                               |                    |               | gRPC calls may take to finish; HTTP requests      |
|                               |                    |               | clients had sent but the server had not read yet  |
|                               |                    |               | are answered too (`services.http_server`)         |
| `COEXIST_OTEL_ENABLED`        | false              | server        | OpenTelemetry spans of requests, the engine and   |
|                               |                    |               | the store (the `otel` extra; `services.tracing`)  |
| `PROMETHEUS_MULTIPROC_DIR`    | `DATA_DIR/prometheus` | `serve --workers N` | N > 1: where the workers' metrics meet; |
|                               |                    |               | emptied at start (`services.metrics`)             |
| `COEXIST_TEST_PG_URL`         | `postgresql://postgres@127.0.0.1:5432/test` | tests | the PostgreSQL server of the tests   |
| `COEXIST_REQUIRE_POSTGRES`    | unset              | tests         | PostgreSQL tests fail instead of skipping         |
| `COEXIST_TEST_REDIS_URL`      | `redis://127.0.0.1:6379/0` | tests | the Redis server of the tests            |
| `COEXIST_REQUIRE_REDIS`       | unset              | tests         | Redis tests fail instead of skipping              |
| `RAY_ADDRESS`                 | unset              | `--backend ray` | the Ray cluster when `--ray-address` is not given |

Reads are open unless a read token is set or `require_read_token` is true; then every request
(REST and gRPC: inference, sessions, the registry, jobs, metrics, docs) must carry the read token
or the admin token (with `require_read_token` and no read token, only the admin token); only
liveness stays open, and `/readyz` without a token answers its status alone (`services.auth`). Settings are built by `get_settings()` on first call, never at import time; tests
pass their own `Settings(...)` to `create_app`.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Literal

from pydantic import Field, SecretStr, field_validator, model_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

from model_store.sql.sql_store import DEFAULT_MAX_ARTIFACT_BYTES

DEFAULT_ADMIN_TOKEN = "dev-token"
MIN_TOKEN_CHARS = 16  # outside development mode (`token_weakness`)
MIN_TOKEN_DISTINCT = 8


class InsecureSettings(RuntimeError):
    """The server was asked to start with a secret left at its public default."""


class Settings(BaseSettings):
    model_config = SettingsConfigDict(env_prefix="COEXIST_", extra="ignore")

    store_url: str | None = Field(default=None, description="model store URL (None: SQLite file)")
    data_dir: Path = Field(default=Path(".coexist"), description="data directory")
    create_store: bool = False
    admin_token: SecretStr = Field(default=SecretStr(DEFAULT_ADMIN_TOKEN))
    read_token: SecretStr | None = None
    require_read_token: bool = False
    dev_mode: bool = False
    max_artifact_bytes: int = Field(default=DEFAULT_MAX_ARTIFACT_BYTES, gt=0)
    max_body_bytes: int = Field(default=16 << 20, ge=1024)
    tls_cert_file: Path | None = None
    tls_key_file: Path | None = None
    host: str = "127.0.0.1"
    allowed_hosts: str = ""  # `Host` names answered; "": derived from `host`
    http_port: int = Field(default=8000, ge=0, le=65535)
    grpc_port: int = Field(default=50051, ge=0, le=65535)
    grpc_enabled: bool = True
    grpc_workers: int = Field(default=8, ge=2, le=256)
    max_episodes: int | None = Field(default=None, ge=1)
    max_episodes_per_client: int | None = Field(default=None, ge=1)
    episode_idle_timeout_s: float = Field(default=60.0, gt=0, le=86400)
    http_max_header_bytes: int = Field(default=64 << 10, ge=1024)
    http_header_timeout_s: float = Field(default=10.0, gt=0, le=3600)
    http_idle_timeout_s: float = Field(default=30.0, gt=0, le=3600)
    http_keep_alive_s: int = Field(default=5, ge=1, le=3600)
    max_connections: int | None = Field(default=None, ge=16)
    refresh_interval_s: float = Field(default=2.0, gt=0, le=3600)
    cache_size: int = Field(default=256, ge=1)
    max_batch: int = Field(default=4096, ge=1)
    session_ttl_s: float = Field(default=300.0, gt=0, le=86400)
    max_sessions: int = Field(default=1000, ge=1)
    max_sessions_per_client: int = Field(default=100, ge=1)
    forwarded_allow_ips: str = ""  # trusted proxies (comma-separated); "": none
    session_prefetch: bool = True
    session_store_url: str | None = None  # Redis or PostgreSQL; None: in this process
    session_secret: SecretStr | None = None  # signs ids and records of the shared store
    workers: int = Field(default=1, ge=1)
    direct_json: bool = True
    log_format: Literal["json", "text"] = "text"
    log_level: Literal["debug", "info", "warning", "error"] = "info"
    shutdown_grace_s: int = Field(default=10, ge=0, le=3600)
    otel_enabled: bool = False  # OpenTelemetry spans (services.tracing; the `otel` extra)
    job_lease_s: float = Field(default=30.0, ge=1.0, le=3600)
    jobs_url: SecretStr | None = None  # the job table's SQL database; None: see the table

    @model_validator(mode="after")
    def _streams_leave_workers(self) -> Settings:
        if self.max_episodes is not None and self.max_episodes >= self.grpc_workers:
            raise ValueError(
                f"COEXIST_MAX_EPISODES ({self.max_episodes}) must be fewer than "
                f"COEXIST_GRPC_WORKERS ({self.grpc_workers}): each open Episode stream holds a "
                "worker thread, and unary calls need some"
            )
        return self

    @field_validator("log_format", "log_level", mode="before")
    @classmethod
    def _lower_case(cls, value: object) -> object:
        return value.lower() if isinstance(value, str) else value  # INFO and info alike

    def resolved_store_url(self) -> str:
        """`store_url`, else `sqlite:///{data_dir}/models.db` (the directory is created)."""
        if self.store_url:
            return self.store_url
        self.data_dir.mkdir(parents=True, exist_ok=True)
        return f"sqlite:///{self.data_dir / 'models.db'}"

    @property
    def creates_store(self) -> bool:
        """Whether a SQLite store file that does not exist may be created: the default one in
        the data directory always, a `store_url` one only with `create_store`."""
        return self.create_store or not self.store_url

    @property
    def reads_need_token(self) -> bool:
        return self.require_read_token or self.read_token is not None

    def _check_tls(self) -> None:
        if (self.tls_cert_file is None) != (self.tls_key_file is None):
            raise InsecureSettings(
                "COEXIST_TLS_CERT_FILE and COEXIST_TLS_KEY_FILE go together: set both or neither"
            )
        if self.tls_cert_file is not None and self.tls_key_file is not None:
            _readable(self.tls_cert_file, "COEXIST_TLS_CERT_FILE")
            _readable(self.tls_key_file, "COEXIST_TLS_KEY_FILE")

    @property
    def tls(self) -> bool:
        return self.tls_cert_file is not None

    def tls_pair(self) -> tuple[bytes, bytes] | None:
        """(certificate chain, private key) as PEM bytes, or None without TLS."""
        if self.tls_cert_file is None or self.tls_key_file is None:
            return None
        return self.tls_cert_file.read_bytes(), self.tls_key_file.read_bytes()

    def accepted_tokens(self) -> tuple[str, ...]:
        """The tokens a read accepts: the read token (if any) and the admin token."""
        read = self.read_token.get_secret_value() if self.read_token else ""
        return tuple(t for t in (read, self.admin_token.get_secret_value()) if t)

    def check_secure(self) -> None:
        """Refuse an empty admin token always, and TLS settings that cannot work (one file of
        the pair, or a file that cannot be read); outside development mode refuse the public
        default and any token that is easy to guess (`token_weakness`), admin or read."""
        if not self.admin_token.get_secret_value().strip():
            raise InsecureSettings("COEXIST_ADMIN_TOKEN is empty: set a secret token")
        self._check_tls()
        if self.session_store_url and self.session_secret is None:
            raise InsecureSettings(
                "COEXIST_SESSION_SECRET is unset: a shared session store "
                "(COEXIST_SESSION_STORE_URL) needs a secret, the same on every replica, to sign "
                "session ids and state (COEXIST_SESSION_SECRET=$(openssl rand -hex 24))"
            )
        if self.dev_mode:
            return
        if self.admin_token.get_secret_value() == DEFAULT_ADMIN_TOKEN:
            raise InsecureSettings(
                "COEXIST_ADMIN_TOKEN is the public default 'dev-token': set a secret token "
                "(COEXIST_ADMIN_TOKEN=$(openssl rand -hex 24)) or, on a development machine, "
                "COEXIST_DEV_MODE=1"
            )
        tokens = [("COEXIST_ADMIN_TOKEN", self.admin_token)]
        if self.read_token is not None:
            tokens.append(("COEXIST_READ_TOKEN", self.read_token))
        if self.session_store_url and self.session_secret is not None:
            tokens.append(("COEXIST_SESSION_SECRET", self.session_secret))
        for name, token in tokens:
            weakness = token_weakness(token.get_secret_value())
            if weakness is not None:
                raise InsecureSettings(
                    f"{name} {weakness}: use a random one (e.g. $(openssl rand -hex 24)) or, on "
                    "a development machine, COEXIST_DEV_MODE=1"
                )


def _readable(path: Path, name: str) -> None:
    try:
        with path.open("rb") as f:
            f.read(1)
    except OSError as err:
        raise InsecureSettings(f"{name}: cannot read {path} ({err.strerror})") from None


def token_weakness(token: str) -> str | None:
    """Why `token` is too easy to guess (None when it is not): shorter than
    `MIN_TOKEN_CHARS`, containing whitespace (a stray space or newline from a copy), or made of
    fewer than `MIN_TOKEN_DISTINCT` different characters (`aaaa...`, `abab...`)."""
    if len(token) < MIN_TOKEN_CHARS:
        return f"has {len(token)} characters, fewer than {MIN_TOKEN_CHARS}"
    if any(c.isspace() for c in token):
        return "contains whitespace"
    if len(set(token)) < MIN_TOKEN_DISTINCT:
        return f"uses fewer than {MIN_TOKEN_DISTINCT} different characters"
    return None


@lru_cache(maxsize=1)
def get_settings() -> Settings:
    """The process's settings from the environment, built on first use."""
    return Settings()
