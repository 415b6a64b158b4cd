"""The store the console tests serve (imported by them; not a test module).

| models                                   | versions | aliases                                 |
|------------------------------------------|----------|-----------------------------------------|
| `particle/{task,impact}/{g}`, all 35 g   | 1        | production, latest                      |
| `cooking/{task,impact}/{r}`, all 5 r     | 1        | production, latest                      |
| `particle/task/a2`                       | 2        | v1: production; v2: latest, candidate   |
| `particle/impact/b3`                     | 2        | v1: production; v2: latest, candidate   |

Version 1 of each: random weights (numpy, scaled so policies depend on the observation and differ
between goals), lineage α 0.05. Every goal has its networks because goal inference scores all
task networks of an env. The two version 2s are registered by the trainer's own `publish_batch`
(so their lineage has the shape training gives: config, seed, code version, a curve, the impact
network's parent task version), with version 1's weights and a made-up curve: promoting one
changes no policy, so the tests that play episodes do not depend on the one that promotes.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import safetensors.numpy
import torch

from envs.registry import get_domain
from model_store.entities import Lineage
from model_store.naming import impact_model_name, task_model_name
from model_store.sql import SqlModelStore
from model_store.testing import qnet_spec, qnet_tensors
from policy.qnet import QNetSpec, StackedQNet
from trainer.config import ImpactConfig, TaskConfig
from trainer.learners import TrainedBatch
from trainer.loop import TrainingCurves
from trainer.publish import publish_batch

ALPHA = 0.05
LAYER_SCALES = (8.0, 2.0)  # qnet_tensors' N(0, 0.1) weights scaled up: policies far from uniform
CURVE = TrainingCurves(
    steps=[100, 200, 300, 400, 500],
    returns_G=[[-60.0], [-41.5], [-30.2], [-22.8], [-19.9]],
    losses_G=[[2.1], [1.4], [0.9], [0.7], [0.6]],
)


def _weights(spec: dict, seed: int) -> bytes:
    tensors = qnet_tensors(spec, seed=seed)
    for k, scale in enumerate(LAYER_SCALES):
        tensors[f"layers.{k}.weight"] *= scale
    return safetensors.numpy.save(tensors)


def _register_env(store: SqlModelStore, env: str, seed_offset: int) -> None:
    domain = get_domain(env)
    spec = qnet_spec(obs_dim=domain.pair_obs_dim, n_actions=domain.n_actions, hidden=(16,))
    for kind, naming, offset in (("task", task_model_name, 0), ("impact", impact_model_name, 500)):
        for k, goal in enumerate(domain.goals):
            name = naming(env, goal)
            store.create_model(
                name,
                env=env,
                kind=kind,
                goals=(goal,),
                obs_dim=domain.pair_obs_dim,
                n_actions=domain.n_actions,
            )
            store.register_version(
                name,
                spec=spec,
                weights=_weights(spec, seed_offset + offset + k),
                lineage=Lineage(config={"alpha": ALPHA}, seed=k, registered_by="pytest"),
                aliases=("latest", "production"),
            )


def _retrained(store: SqlModelStore, name: str) -> StackedQNet:
    """Version 1's weights as a one-member stack: a "retrained" version 2 that acts exactly as
    version 1, so promoting it (a test does) changes no episode another test plays."""
    spec = QNetSpec.from_json(store.get_version(name, 1).spec)
    tensors = safetensors.numpy.load(store.load_weights(name, 1))
    return StackedQNet.from_members(spec, [{k: torch.tensor(v) for k, v in tensors.items()}])


def _second_versions(store: SqlModelStore) -> None:
    nets = _retrained(store, "particle/task/a2")
    task_config = replace(TaskConfig(), hidden=nets.spec.hidden)
    task = TrainedBatch("task", [("a2",)], nets, nets.spec, task_config, 11, CURVE)
    publish_batch(store, task, serve_alias="candidate", registered_by="pytest")
    nets = _retrained(store, "particle/impact/b3")
    impact_config = replace(ImpactConfig(), hidden=nets.spec.hidden)
    impact = TrainedBatch("impact", [("b3",)], nets, nets.spec, impact_config, 12, CURVE)
    parents: dict[tuple[str, ...], list[str]] = {("b3",): ["particle/task/b3/1"]}
    publish_batch(store, impact, parents=parents, serve_alias="candidate", registered_by="pytest")


def build_console_zoo(path: Path) -> str:
    """Register the zoo into a new SQLite file at `path`; its URL."""
    url = f"sqlite:///{path}"
    with SqlModelStore(url) as store:
        _register_env(store, "particle", 0)
        _register_env(store, "cooking", 1000)
        _second_versions(store)
    return url
