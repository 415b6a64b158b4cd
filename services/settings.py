"""Settings of the coexist servers: one pydantic-settings class, read from `COEXIST_*` variables.

| variable (`COEXIST_` + field) | default            | meaning                          |
|-------------------------------|--------------------|----------------------------------|
| `STORE_URL`                   | SQLite in data_dir | model store database URL         |
| `DATA_DIR`                    | `.coexist`         | where the SQLite file lives      |
| `ADMIN_TOKEN`                 | `dev-token`        | bearer token for writes          |
| `READ_TOKEN`                  | unset              | bearer token for reads           |
| `REQUIRE_READ_TOKEN`          | false              | reads need a token               |
| `DEV_MODE`                    | false              | allow the default admin token    |
| `MAX_ARTIFACT_BYTES`          | 64 MiB             | upload size limit                |
| `HOST`                        | `127.0.0.1`        | address to listen on             |
| `HTTP_PORT`                   | 8000               | REST port                        |
| `GRPC_PORT`                   | 50051              | gRPC port (0: any free port)     |
| `GRPC_ENABLED`                | true               | serve gRPC beside REST           |
| `GRPC_WORKERS`                | 8                  | gRPC thread pool size            |
| `REFRESH_INTERVAL_S`          | 2.0                | how often aliases are re-checked |
| `CACHE_SIZE`                  | 256                | networks kept loaded (LRU)       |
| `MAX_BATCH`                   | 4096               | rows allowed in one act:batch    |

Reads are open unless a read token is set or `require_read_token` is true; then a request must
carry the read token or the admin token (with `require_read_token` and no read token, only the
admin token). Settings are built by `get_settings()` on first call, never at import time; tests
pass their own `Settings(...)` to `create_app`.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

from pydantic import Field, SecretStr
from pydantic_settings import BaseSettings, SettingsConfigDict

from model_store.sql.sql_store import DEFAULT_MAX_ARTIFACT_BYTES

DEFAULT_ADMIN_TOKEN = "dev-token"


class InsecureSettings(RuntimeError):
    """The server was asked to start with a secret left at its public default."""


class Settings(BaseSettings):
    model_config = SettingsConfigDict(env_prefix="COEXIST_", extra="ignore")

    store_url: str | None = Field(default=None, description="model store URL (None: SQLite file)")
    data_dir: Path = Field(default=Path(".coexist"), description="data directory")
    admin_token: SecretStr = Field(default=SecretStr(DEFAULT_ADMIN_TOKEN))
    read_token: SecretStr | None = None
    require_read_token: bool = False
    dev_mode: bool = False
    max_artifact_bytes: int = Field(default=DEFAULT_MAX_ARTIFACT_BYTES, gt=0)
    host: str = "127.0.0.1"
    http_port: int = Field(default=8000, ge=0, le=65535)
    grpc_port: int = Field(default=50051, ge=0, le=65535)
    grpc_enabled: bool = True
    grpc_workers: int = Field(default=8, ge=1, le=256)
    refresh_interval_s: float = Field(default=2.0, gt=0, le=3600)
    cache_size: int = Field(default=256, ge=1)
    max_batch: int = Field(default=4096, ge=1)

    def resolved_store_url(self) -> str:
        """`store_url`, else `sqlite:///{data_dir}/models.db` (the directory is created)."""
        if self.store_url:
            return self.store_url
        self.data_dir.mkdir(parents=True, exist_ok=True)
        return f"sqlite:///{self.data_dir / 'models.db'}"

    @property
    def reads_need_token(self) -> bool:
        return self.require_read_token or self.read_token is not None

    def check_secure(self) -> None:
        """Refuse the public default admin token outside development mode."""
        if self.admin_token.get_secret_value() == DEFAULT_ADMIN_TOKEN and not self.dev_mode:
            raise InsecureSettings(
                "COEXIST_ADMIN_TOKEN is the public default 'dev-token': set a secret token "
                "(COEXIST_ADMIN_TOKEN=...) or, on a development machine, COEXIST_DEV_MODE=1"
            )
        if not self.admin_token.get_secret_value():
            raise InsecureSettings("COEXIST_ADMIN_TOKEN is empty: set a secret token")


@lru_cache(maxsize=1)
def get_settings() -> Settings:
    """The process's settings from the environment, built on first use."""
    return Settings()
