"""AAIL-B in the kitchen (R2 and R3 of `policy.regret_bound`): before the ego's dish is served it
acts with its task policy; once it is served (the `served` feature; final, `goal_is_final`) the
task Q is flat and the blend is the impact network's policy, whatever the task network prefers."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest
import torch
from zoo_fixtures import ZOO_ALPHA, random_weights

from envs.cooking.batched import BatchedCookingWorld
from envs.cooking.domain import COOKING
from envs.cooking.observation import SERVED
from model_store.entities import Lineage
from model_store.naming import impact_model_name, task_model_name
from model_store.sql import SqlModelStore
from policy.qnet import QNetSpec, QNetwork
from services.engine import ActRequest, InferenceEngine, PartnerSpec

SPEC = QNetSpec(obs_dim=COOKING.pair_obs_dim, n_actions=5, hidden=(16,))
EGO, PARTNER = "TomatoLettuceSalad", "CarrotBanana"
SEEDS = {"task": 1, "impact": 2}


@pytest.fixture
def kitchen_store(tmp_path) -> Iterator[SqlModelStore]:
    store = SqlModelStore(f"sqlite:///{tmp_path / 'models.db'}")
    for kind, name, goal in (
        ("task", task_model_name("cooking", EGO), EGO),
        ("task", task_model_name("cooking", PARTNER), PARTNER),
        ("impact", impact_model_name("cooking", PARTNER), PARTNER),
    ):
        store.create_model(
            name, env="cooking", kind=kind, goals=(goal,), obs_dim=SPEC.obs_dim, n_actions=5
        )
        store.register_version(
            name,
            spec=SPEC.to_json(),
            weights=random_weights(SPEC, SEEDS[kind]),
            lineage=Lineage(config={"alpha": ZOO_ALPHA}, seed=SEEDS[kind], registered_by="pytest"),
            aliases=("latest", "production"),
        )
    yield store
    store.close()


def _q(seed: int, view: np.ndarray) -> np.ndarray:
    """The Q-vector of the network `random_weights(SPEC, seed)` registered, in float64."""
    torch.manual_seed(seed)
    net = QNetwork(SPEC)
    last = net.layers[-1]
    assert isinstance(last, torch.nn.Linear)
    with torch.no_grad():
        last.weight.mul_(4.0)
        last.bias.mul_(4.0)
        return net(torch.as_tensor(view[None], dtype=torch.float32))[0].double().numpy()


def _boltzmann(q: np.ndarray) -> np.ndarray:
    z = np.exp((q - q.max()) / ZOO_ALPHA)
    return z / z.sum()


def test_before_the_dish_the_task_policy_after_it_the_impact_policy(kitchen_store) -> None:
    obs = BatchedCookingWorld("coexistence", np.array([[EGO, PARTNER]])).reset()[0, 0]
    served = obs.copy()
    served[SERVED] = 1.0  # the ego's dish is done
    engine = InferenceEngine(kitchen_store)
    partners = (PartnerSpec(1, goal=PARTNER),)
    rows = np.stack([obs, served])
    batch = engine.act(ActRequest("cooking", EGO, rows, partners, method="aail_bounded", seed=0))
    singles = [
        engine.act(ActRequest("cooking", EGO, row[None], partners, method="aail_bounded", seed=0))[
            0
        ]
        for row in rows
    ]
    task_policy = _boltzmann(_q(SEEDS["task"], obs))
    impact_policy = _boltzmann(_q(SEEDS["impact"], served))  # two cooks: the impact view is obs
    assert task_policy.max() > 0.5  # the task network does prefer an action here
    for before, after in (batch, singles):
        np.testing.assert_allclose(before.probs, task_policy, atol=1e-5)  # R2: SL before
        np.testing.assert_allclose(after.probs, impact_policy, atol=1e-5)  # R3: flat task Q
        assert after.task_weight == pytest.approx(0.0, abs=1e-9)
    paper = engine.act(ActRequest("cooking", EGO, served[None], partners, method="aail"))[0]
    assert not np.allclose(paper.probs, impact_policy, atol=1e-3)  # eq. 9 as printed does not
