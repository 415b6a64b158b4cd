"""A particle zoo for the session tests (imported by them; not a test module): a task and an impact
network for EVERY goal of the catalogue (goal inference evaluates all 35 task networks), random
weights (numpy, no training), lineage α 0.05, aliases production and latest.

    template = build_session_zoo(path)            # once; then copy or open read-only
    register_session_zoo(postgres_url)            # the same zoo in another store
    partner_action(engine, obs, partner=1, goal="c1")   # the action goal c1's task policy prefers
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import safetensors.numpy

from envs.particle.goals import GOAL_IDS
from model_store.entities import Lineage
from model_store.naming import impact_model_name, task_model_name
from model_store.sql import SqlModelStore
from model_store.testing import qnet_spec, qnet_tensors
from services.engine import InferenceEngine

ALPHA = 0.05
# qnet_tensors draws N(0, 0.1) weights: scaled up so that each goal's policy depends on the
# observation and differs from the others' (not the bias's arg max everywhere)
LAYER_SCALES = (8.0, 2.0)


def _weights(spec: dict, seed: int) -> bytes:
    tensors = qnet_tensors(spec, seed=seed)
    for k, scale in enumerate(LAYER_SCALES):
        tensors[f"layers.{k}.weight"] *= scale
    return safetensors.numpy.save(tensors)


def build_session_zoo(path: Path) -> str:
    """Register the zoo into a new SQLite file at `path`; its URL."""
    url = f"sqlite:///{path}"
    register_session_zoo(url)
    return url


def register_session_zoo(url: str) -> None:
    """Register the zoo into the (empty) store at `url`: SQLite or PostgreSQL."""
    spec = qnet_spec(obs_dim=8, n_actions=5, hidden=(16,))
    with SqlModelStore(url) as store:
        for kind, naming, offset in (
            ("task", task_model_name, 0),
            ("impact", impact_model_name, 500),
        ):
            for k, goal in enumerate(GOAL_IDS):
                name = naming("particle", goal)
                store.create_model(
                    name, env="particle", kind=kind, goals=(goal,), obs_dim=8, n_actions=5
                )
                store.register_version(
                    name,
                    spec=spec,
                    weights=_weights(spec, offset + k),
                    lineage=Lineage(config={"alpha": ALPHA}, seed=k, registered_by="pytest"),
                    aliases=("latest", "production"),
                )


def partner_action(engine: InferenceEngine, obs: np.ndarray, partner: int, goal: str) -> int:
    """The most likely action of `goal`'s task policy for `partner`, on the ego's `obs`."""
    scores = [
        engine.goal_log_likelihoods("particle", obs, [partner], [a])[0, GOAL_IDS.index(goal)]
        for a in range(5)
    ]
    return int(np.argmax(scores))


_TEMPLATE: dict[str, Path] = {}


def session_zoo_template(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The zoo's SQLite file, built once per test process (open it read-only, or copy it)."""
    if "path" not in _TEMPLATE:
        path = tmp_path_factory.mktemp("session_zoo") / "models.db"
        build_session_zoo(path)
        _TEMPLATE["path"] = path
    return _TEMPLATE["path"]


def random_observation(rng: np.random.Generator, n_agents: int = 2) -> np.ndarray:
    """An ego observation of a scene of `n_agents` (positions and velocities in range)."""
    return rng.uniform(-1.0, 1.0, 4 * n_agents)
