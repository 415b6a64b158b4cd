"""The Ray backend against a real local Ray instance (`ray.init(num_cpus=2)`, one per module).

- a tiny zoo trained through Ray is registered exactly as the local backend registers it: same
  models, version counts, aliases, tags, weights (training is deterministic given the seed) and
  lineage, except the job marker `config["job"]` that only the Ray backend writes;
- a worker killed mid-publish (`os._exit` after its first registration, first attempt only) is
  retried by Ray and leaves exactly one version per network;
- `coexist train task --backend ray` goes the same way from the command line.
Without Ray installed (it is the optional `ray` extra) the module is skipped.
"""

from __future__ import annotations

import json
import os
import sys
import uuid
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import psycopg
import pytest
from sqlalchemy.engine import URL, make_url
from typer.testing import CliRunner

from model_store.entities import ModelVersion
from model_store.sql import SqlModelStore
from trainer.backends.jobs import impact_stage, joint_stage, task_stage
from trainer.backends.once import JOB_CONFIG_KEY
from trainer.backends.ray_cluster import job_id_for, portable_store_url, run_on_ray
from trainer.config import ImpactConfig, JointConfig, TaskConfig
from trainer.zoo import RunState, run_impacts, run_joint, run_tasks

ray = pytest.importorskip("ray", reason="Ray is the optional extra: pip install 'coexist[ray]'")

pytestmark = pytest.mark.slow  # Ray's start alone takes ~9 s on 2 cores

PG_URL = os.environ.get("COEXIST_TEST_PG_URL", "postgresql://postgres@127.0.0.1:5432/test")
TINY: dict[str, Any] = dict(
    total_steps=60,
    warmup_steps=10,
    envs_per_net=4,
    batch_size=16,
    hidden=(16,),
    eval_episodes=4,
    eval_steps=20,
)
GOALS = ["a2", "b3", "c"]
COMBOS = [["a2", "b3"]]


def _no_progress(description: str, total: int) -> Any:
    return lambda done, total_: None


@pytest.fixture(scope="module")
def ray_session() -> Iterator[None]:
    # the workers must be able to unpickle this module's crash hook by value
    ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()


@pytest.fixture
def store_url(tmp_path: Path) -> Iterator[str]:
    """PostgreSQL (a fresh schema) when the server answers, as on a cluster; else SQLite."""
    try:
        with psycopg.connect(PG_URL, autocommit=True, connect_timeout=3) as conn:
            schema = f"coexist_ray_{uuid.uuid4().hex[:12]}"
            conn.execute(f'CREATE SCHEMA "{schema}"')
    except psycopg.Error:
        if os.environ.get("COEXIST_REQUIRE_POSTGRES"):
            raise
        yield f"sqlite:///{tmp_path / 'ray-store' / 'models.db'}"
        return
    url = make_url(PG_URL).update_query_dict({"options": f"-csearch_path={schema}"})
    yield url.render_as_string(hide_password=False)
    with psycopg.connect(PG_URL, autocommit=True) as conn:
        conn.execute(f'DROP SCHEMA IF EXISTS "{schema}" CASCADE')


def _configs() -> tuple[TaskConfig, ImpactConfig, JointConfig]:
    return (
        replace(TaskConfig(), **TINY),
        replace(ImpactConfig(), **TINY),
        replace(JointConfig(), **TINY),
    )


def _registry(store: SqlModelStore) -> dict[str, Any]:
    """Everything registered, in a comparable form (the job marker set aside)."""
    out: dict[str, Any] = {}
    for model in store.list_models(page_size=1000).items:
        versions = []
        for v in store.list_versions(model.name):
            lineage = v.lineage.to_json()
            lineage["config"] = {k: x for k, x in lineage["config"].items() if k != JOB_CONFIG_KEY}
            versions.append((v.version, v.sha256, lineage))
        out[model.name] = (model.aliases, model.tags, versions)
    return out


def test_workers_get_the_store_as_a_url_object_the_password_put_back_into_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """What `coexist train --backend ray` hands the tasks: the store's URL without its password
    and the password apart (`reopen_url`, `reopen_password`) become one URL object, which
    travels pickled as the tasks' argument, never rendered into a string."""
    url = portable_store_url("postgresql://u@db:5432/zoo", "s3cret")
    assert isinstance(url, URL) and url.password == "s3cret"
    assert url.drivername == "postgresql+psycopg" and "s3cret" not in repr(url)
    assert ray.cloudpickle.loads(ray.cloudpickle.dumps(url)) == url
    assert portable_store_url(url) == url  # a URL object with its password is kept as it is
    monkeypatch.chdir(tmp_path)
    local = portable_store_url("sqlite:///runs/models.db")
    assert isinstance(local, URL) and local.database == str(tmp_path / "runs" / "models.db")


def test_ray_zoo_is_registered_exactly_as_the_local_backend_registers_it(
    ray_session: None, store_url: str, tmp_path: Path
) -> None:
    task_cfg, impact_cfg, joint_cfg = _configs()
    local_url = f"sqlite:///{tmp_path / 'local' / 'models.db'}"
    with SqlModelStore(local_url) as local:
        run = RunState.open(tmp_path / "local-run", "fp", resume=False)
        common: dict[str, Any] = dict(seed=7, run=run, progress=_no_progress)
        batches = run_tasks(local, GOALS, task_cfg, goals_per_batch=2, **common)
        batches += run_impacts(local, GOALS, impact_cfg, goals_per_batch=2, **common)
        batches += run_joint(local, COMBOS, joint_cfg, **common)
        expected = _registry(local)
        local_done = run.done

    ray_run = RunState.open(tmp_path / "ray-run", "fp", resume=False)
    stages = [
        task_stage(GOALS, task_cfg, seed=7, per_batch=2),
        impact_stage(GOALS, impact_cfg, seed=7, per_batch=2),
        joint_stage(COMBOS, joint_cfg, seed=7),
    ]
    outcomes = run_on_ray(store_url, stages, run=ray_run, job_id="run-1")
    with SqlModelStore(store_url) as store:
        got = _registry(store)
        marker = store.get_version("particle/impact/c", 1).lineage.config[JOB_CONFIG_KEY]
    assert sorted(got) == sorted(expected) and len(got) == 3 + 3 + 1
    for name in expected:
        assert got[name] == expected[name], name
    assert marker == "run-1/impact:c"
    # the driver recorded the same batches, with the same refs, as the local loops
    assert ray_run.done == local_done
    assert [(o.kind, o.goals, o.seed) for o in outcomes] == [
        (b.kind, b.goals, b.seed) for b in batches
    ]
    # 60-step networks fail their gates: both backends trained the goals again (tasks, impacts)
    assert "task-retry-1" in ray_run.done and "impact-retry-1" in ray_run.done
    # resuming the finished run submits nothing
    assert run_on_ray(store_url, stages, run=ray_run, job_id="run-1") == []


class CrashAfterFirstRegistration:
    """Kills the worker (no cleanup, like an OOM kill) right after the first version it
    registers, on the first attempt only: the flag file marks that the crash happened."""

    def __init__(self, flag: Path) -> None:
        self.flag = flag

    def __call__(self, version: ModelVersion) -> None:
        if not self.flag.exists():
            self.flag.write_text(version.ref)
            os._exit(1)


def test_a_worker_killed_mid_publish_is_retried_without_duplicate_versions(
    ray_session: None, store_url: str, tmp_path: Path
) -> None:
    task_cfg, _, _ = _configs()
    flag = tmp_path / "crashed"
    run = RunState.open(tmp_path / "run", "fp", resume=False)
    outcomes = run_on_ray(
        store_url,
        [task_stage(["a2", "b3"], task_cfg, seed=1, per_batch=2, gate_retries=0)],
        run=run,
        job_id="run-2",
        on_register=CrashAfterFirstRegistration(flag),
    )
    assert flag.read_text() == "particle/task/a2/1"  # the first attempt died after one version
    with SqlModelStore(store_url) as store:
        for goal in ("a2", "b3"):
            versions = store.list_versions(f"particle/task/{goal}")
            assert [v.version for v in versions] == [1], goal
            assert versions[0].lineage.config[JOB_CONFIG_KEY] == "run-2/task:a2,b3"
    assert outcomes[0].versions == ["particle/task/a2/1", "particle/task/b3/1"]


def test_train_task_cli_with_the_ray_backend(
    ray_session: None, store_url: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import cli.train
    from cli.main import app

    monkeypatch.setattr(cli.train, "_configs", lambda steps, env="particle": _configs())
    run_dir = tmp_path / "cli-run"
    args = [
        "train",
        "task",
        "--goals",
        "a2,b3,c",
        "--goals-per-batch",
        "2",
        "--backend",
        "ray",
        "--store-url",
        store_url,
        "--run-dir",
        str(run_dir),
    ]
    result = CliRunner().invoke(app, args)
    # the tiny configurations train networks that may fail their gates: exit 4 says so
    assert result.exit_code in (0, 4), result.output
    assert result.exit_code == 0 or "failed their gate" in result.output
    assert "trained networks" in result.output  # the summary table
    job_id = (run_dir / "job-id").read_text().strip()
    done = json.loads((run_dir / "run.json").read_text())["done"]
    assert {"task:a2,b3", "task:c"} <= set(done) and done["task:c"] == ["particle/task/c/1"]
    with SqlModelStore(store_url) as store:
        v = store.get_version("particle/task/c", 1)
        assert v.lineage.config[JOB_CONFIG_KEY] == f"{job_id}/task:c"
    # --resume keeps the job id; a new run gets a new one
    assert job_id_for(run_dir, resume=True) == job_id
    assert job_id_for(run_dir, resume=False) != job_id


def test_the_local_backend_and_the_cli_never_import_ray() -> None:
    import subprocess

    code = (
        "import sys\n"
        "from typer.testing import CliRunner\n"
        "import cli.main, cli.train, trainer.zoo, trainer.backends.jobs\n"
        "assert CliRunner().invoke(cli.main.app, ['train', 'zoo', '--help']).exit_code == 0\n"
        "assert 'ray' not in sys.modules, 'ray was imported'\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
