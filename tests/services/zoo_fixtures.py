"""The tiny zoo of the service and SDK tests (not a test module): a registered zoo in a SQLite
store, as fixtures that tests/services/conftest.py and tests/sdk/conftest.py take from here.

`tiny_zoo_store` is a `SqlModelStore` (fresh copy per test, so tests may move aliases) holding:

| model                          | versions | aliases                                   |
|--------------------------------|----------|-------------------------------------------|
| `particle/task/{g}`, g in TASK_GOALS     | 1 | production, latest                  |
| `particle/task/a2`             | 2        | v1: production; v2: latest                |
| `particle/impact/{g}`, g in IMPACT_GOALS | 1 | production, latest                  |
| `particle/joint/a2+b3`         | 1        | production, latest (obs_dim 8: 2 agents)  |
| `particle/joint/a2+b3+c1`      | 1        | production, latest (obs_dim 12: 3 agents) |

Specs: `QNetSpec(obs_dim=8, n_actions=5, hidden=(16,))` (joint: the whole observation), weights
from a seeded `QNetwork` scaled up so the policies are far from uniform. Lineage `config.alpha` is
0.05 for every model except `particle/task/b3`, which has none (the engine then uses 0.02).
`tiny_zoo` gives the same store plus these tables; `act_client` a TestClient of a minimal app
serving the inference routes over it.
"""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import torch
from fastapi import FastAPI
from fastapi.testclient import TestClient

from model_store.entities import Lineage
from model_store.naming import impact_model_name, joint_model_name, task_model_name
from model_store.sql import SqlModelStore
from policy.qnet import QNetSpec, QNetwork, weights_to_safetensors
from services.engine import InferenceEngine
from services.rest import install_error_handlers as install_act_error_handlers
from services.rest import router as act_router

TASK_GOALS = ("a2", "b3", "c1", "d4", "e0", "c")
IMPACT_GOALS = ("a2", "b3", "c1", "d4", "e0", "c")
JOINT_COMBOS = (("a2", "b3"), ("a2", "b3", "c1"))
PAIR_SPEC = QNetSpec(obs_dim=8, n_actions=5, hidden=(16,))
ZOO_ALPHA = 0.05
NO_ALPHA_TASK = "b3"


@dataclass(frozen=True)
class TinyZoo:
    store: SqlModelStore
    task_goals: tuple[str, ...] = TASK_GOALS
    impact_goals: tuple[str, ...] = IMPACT_GOALS
    joint_combos: tuple[tuple[str, ...], ...] = JOINT_COMBOS
    alpha: float = ZOO_ALPHA
    no_alpha_task: str = NO_ALPHA_TASK

    def register(
        self, name: str, kind: str, goals: tuple[str, ...], spec: QNetSpec, seed: int, **kwargs: Any
    ) -> int:
        """Register one more version in the zoo's store (see `register`); its number."""
        return register(self.store, name, kind, goals, spec, seed, **kwargs)


def random_weights(spec: QNetSpec, seed: int, scale: float = 4.0) -> bytes:
    """Safetensors bytes of a seeded QNetwork whose outputs are scaled by `scale`."""
    torch.manual_seed(seed)
    net = QNetwork(spec)
    last = net.layers[-1]
    assert isinstance(last, torch.nn.Linear)
    with torch.no_grad():
        last.weight.mul_(scale)
        last.bias.mul_(scale)
    return weights_to_safetensors(net)


def register(
    store: SqlModelStore,
    name: str,
    kind: str,
    goals: tuple[str, ...],
    spec: QNetSpec,
    seed: int,
    *,
    alpha: float | None = ZOO_ALPHA,
    aliases: tuple[str, ...] = ("latest", "production"),
) -> int:
    """Create the model if needed and register one version; returns its number."""
    store.create_model(
        name,
        env="particle",
        kind=kind,
        goals=goals,
        obs_dim=spec.obs_dim,
        n_actions=spec.n_actions,
        exist_ok=True,
    )
    config = {} if alpha is None else {"alpha": alpha}
    version = store.register_version(
        name,
        spec=spec.to_json(),
        weights=random_weights(spec, seed),
        lineage=Lineage(config=config, seed=seed, registered_by="pytest"),
        aliases=aliases,
    )
    return version.version


def _build_zoo(url: str) -> None:
    with SqlModelStore(url) as store:
        for k, goal in enumerate(TASK_GOALS):
            alpha = None if goal == NO_ALPHA_TASK else ZOO_ALPHA
            register(
                store, task_model_name("particle", goal), "task", (goal,), PAIR_SPEC, k, alpha=alpha
            )
        register(
            store,
            task_model_name("particle", "a2"),
            "task",
            ("a2",),
            PAIR_SPEC,
            99,
            aliases=("latest",),
        )
        for k, goal in enumerate(IMPACT_GOALS):
            register(
                store, impact_model_name("particle", goal), "impact", (goal,), PAIR_SPEC, 100 + k
            )
        for k, combo in enumerate(JOINT_COMBOS):
            spec = QNetSpec(obs_dim=4 * len(combo), n_actions=5, hidden=(16,))
            name = joint_model_name("particle", combo[0], list(combo[1:]))
            register(store, name, "joint", combo, spec, 200 + k)


@pytest.fixture(scope="session")
def _tiny_zoo_template(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("tiny_zoo") / "models.db"
    _build_zoo(f"sqlite:///{path}")
    return path


@pytest.fixture
def tiny_zoo_store(_tiny_zoo_template: Path, tmp_path: Path) -> Iterator[SqlModelStore]:
    """A SqlModelStore holding the tiny zoo (a private copy: tests may change it)."""
    target = tmp_path / "zoo" / "models.db"
    target.parent.mkdir()
    for suffix in ("", "-wal", "-shm"):
        source = Path(f"{_tiny_zoo_template}{suffix}")
        if source.exists():
            shutil.copy(source, f"{target}{suffix}")
    with SqlModelStore(f"sqlite:///{target}") as store:
        yield store


@pytest.fixture
def tiny_zoo(tiny_zoo_store: SqlModelStore) -> TinyZoo:
    return TinyZoo(tiny_zoo_store)


@pytest.fixture
def act_client(tiny_zoo_store: SqlModelStore) -> Iterator[TestClient]:
    """A TestClient of a minimal app: the inference router, its error handlers and an engine
    over the tiny zoo (`app.state.engine`)."""
    app = FastAPI()
    app.include_router(act_router)
    install_act_error_handlers(app)
    app.state.engine = InferenceEngine(tiny_zoo_store)
    with TestClient(app) as client:
        yield client
