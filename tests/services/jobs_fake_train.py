"""A stand-in for `coexist train`, run by the job tests' runner instead of the real trainer.

    COEXIST_STORE_URL=... python jobs_fake_train.py MODE   # the runner sets the variable

| mode       | does                                                                      |
|------------|---------------------------------------------------------------------------|
| `ok`       | prints a line, exits 0                                                    |
| `fail`     | prints a line, exits 3                                                    |
| `sleep`    | prints `training started`, then sleeps a minute (to be cancelled)        |
| `stubborn` | the same, but ignores SIGTERM (only SIGKILL stops it)                     |
| `register` | registers one version of `particle/task/a2` in the store, then sleeps    |
| `secrets`  | the same, opening the store as `coexist train` does, and says where the   |
|            | password of its store and publish-lock connections came from (PostgreSQL) |

Not a test module: `jobs_fakes.fake_command` runs it.
"""

from __future__ import annotations

import os
import signal
import sys
import time


def _register(store_url: str) -> None:
    from model_store.entities import Lineage
    from model_store.sql import SqlModelStore
    from policy.qnet import QNetSpec, QNetwork, weights_to_safetensors

    spec = QNetSpec(obs_dim=8, n_actions=5, hidden=(4,))
    with SqlModelStore(store_url) as store:
        store.create_model(
            "particle/task/a2",
            env="particle",
            kind="task",
            goals=("a2",),
            obs_dim=8,
            n_actions=5,
            exist_ok=True,
        )
        version = store.register_version(
            "particle/task/a2",
            spec=spec.to_json(),
            weights=weights_to_safetensors(QNetwork(spec)),
            lineage=Lineage(seed=0, registered_by="jobs_fake_train"),
        )
    print(f"registered {version.ref}", flush=True)


def _password_source(password: str | None) -> str:
    """Where a connection's password came from, without showing it (this goes to the log)."""
    if not password:
        return "none"
    return "PGPASSWORD" if password == os.environ.get("PGPASSWORD") else "elsewhere"


def _say_password_sources(store_url: str) -> None:
    """The password each PostgreSQL connection of the trainer sent (libpq's, whatever its
    source): the store's engine, and the publish lock's connection (`trainer.backends.once`)."""
    from model_store.sql.engine import create_store_engine, normalise_url
    from trainer.backends.once import lock_connection, publish_lock

    engine = create_store_engine(store_url)
    try:
        connection = engine.raw_connection()
        assert connection.driver_connection is not None  # psycopg's own connection
        store_password = connection.driver_connection.info.password
        connection.close()
    finally:
        engine.dispose()
    print(f"store connection password: {_password_source(store_password)}", flush=True)
    with (
        publish_lock(store_url, "fake-job/secrets"),
        lock_connection(normalise_url(store_url)) as c,
    ):
        print(f"publish lock connection password: {_password_source(c.info.password)}", flush=True)


def main(mode: str) -> int:
    if mode == "ok":
        print("trained every batch", flush=True)
        return 0
    if mode == "fail":
        print("boom: the trainer failed", flush=True)
        return 3
    if mode == "stubborn":
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
    if mode == "register":
        _register(os.environ["COEXIST_STORE_URL"])  # as the real trainer: never in argv
    if mode == "secrets":
        from model_store.defaults import default_store_url

        _register(default_store_url())  # `COEXIST_STORE_URL`, as `coexist train` reads it
        _say_password_sources(default_store_url())
    print(f"training started (pid {os.getpid()})", flush=True)
    time.sleep(60)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
