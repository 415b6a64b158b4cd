"""AAIL-B with a goal monitor (`trainer.monitor`) where the environment does not answer: the
monitor's keeping actions are R4's K and the goal is reached where K is not empty (R2); the
answer names the monitor; without a monitor, R1 on every row."""

from __future__ import annotations

import numpy as np
import torch

from model_store.entities import Lineage
from model_store.naming import monitor_model_name
from model_store.sql import SqlModelStore
from policy.blend import blend
from policy.qnet import QNetwork, weights_to_safetensors
from policy.regret_bound import DEFAULT_EPSILON_PER_ALPHA, keep_goal_rows
from services.engine import ActRequest, InferenceEngine, PartnerSpec
from tests.services.engine.test_engine_reference import ATOL, _q
from tests.services.zoo_fixtures import PAIR_SPEC

OBS = np.array([[0.1, 0.5, 0, 0, 0.7, 0.6, 0, 0], [0.6, 0.5, 0.2, 0, 0.7, 0.6, 0, 0]])
PARTNERS = (PartnerSpec(1, goal="b3"),)


def _register_monitor(store: SqlModelStore, goal: str, logits: list[float]) -> int:
    """A monitor whose logits are `logits` on every input (zero weights, the bias alone)."""
    net = QNetwork(PAIR_SPEC)
    with torch.no_grad():
        for parameter in net.parameters():
            parameter.zero_()
        last = net.layers[-1]
        assert isinstance(last, torch.nn.Linear)
        last.bias.copy_(torch.tensor(logits))
    name = monitor_model_name("particle", goal)
    store.create_model(
        name, env="particle", kind="monitor", goals=(goal,), obs_dim=8, n_actions=5, exist_ok=True
    )
    return store.register_version(
        name,
        spec=PAIR_SPEC.to_json(),
        weights=weights_to_safetensors(net),
        lineage=Lineage(config={}, seed=0, registered_by="pytest"),
        aliases=("latest", "production"),
    ).version


def _expected(tiny_zoo, kept_A: np.ndarray) -> np.ndarray:
    """Per row: the flat task Q (R3) blended with ε (R1), restricted to K (R4)."""
    rows = []
    for row in OBS:
        q_task = _q(tiny_zoo.store, "particle/task/a2", None, row)[None]
        q_impact = _q(tiny_zoo.store, "particle/impact/b3", None, row)[None, None]
        flat = np.full_like(q_task, q_task.mean())
        epsilon = DEFAULT_EPSILON_PER_ALPHA * tiny_zoo.alpha
        probs = blend("aail_bounded", flat, q_impact, tiny_zoo.alpha, regret_bound=epsilon)
        rows.append(keep_goal_rows(probs.probs_BA, kept_A[None])[0])
    return np.array(rows)


def test_the_monitor_answers_where_the_environment_is_not_asked(tiny_zoo) -> None:
    version = _register_monitor(tiny_zoo.store, "a2", [5.0, -5.0, 5.0, -5.0, 5.0])
    engine = InferenceEngine(tiny_zoo.store, goal_oracle=False)
    rows = engine.act(ActRequest("particle", "a2", OBS, PARTNERS))
    kept_A = np.array([True, False, True, False, True])
    np.testing.assert_allclose([r.probs for r in rows], _expected(tiny_zoo, kept_A), atol=ATOL)
    for row in rows:
        assert np.asarray(row.probs)[~kept_A].max() == 0.0  # R4: never a losing action
        monitors = [m for m in row.models if m.role == "monitor"]
        assert [(m.name, m.version, m.goal) for m in monitors] == [
            ("particle/monitor/a2", version, "a2")
        ]
    # the other methods ask no monitor
    [sl] = engine.act(ActRequest("particle", "a2", OBS[:1], PARTNERS, method="sl"))
    assert all(m.role != "monitor" for m in sl.models)


def test_an_engine_told_not_to_ask_monitors_bounds_every_row(tiny_zoo) -> None:
    _register_monitor(tiny_zoo.store, "a2", [5.0, -5.0, 5.0, -5.0, 5.0])
    blind = InferenceEngine(tiny_zoo.store, goal_oracle=False, goal_monitors=False)
    rows = blind.act(ActRequest("particle", "a2", OBS, PARTNERS))
    assert all(m.role != "monitor" for row in rows for m in row.models)
    for row, obs in zip(rows, OBS, strict=True):
        q_task = _q(tiny_zoo.store, "particle/task/a2", None, obs)[None]
        q_impact = _q(tiny_zoo.store, "particle/impact/b3", None, obs)[None, None]
        epsilon = DEFAULT_EPSILON_PER_ALPHA * tiny_zoo.alpha
        want = blend("aail_bounded", q_task, q_impact, tiny_zoo.alpha, regret_bound=epsilon)
        np.testing.assert_allclose(row.probs, want.probs_BA[0], atol=ATOL)
    # the environment answers first: with the oracle the monitor is not asked
    with_oracle = InferenceEngine(tiny_zoo.store).act(ActRequest("particle", "a2", OBS, PARTNERS))
    assert all(m.role != "monitor" for row in with_oracle for m in row.models)


def test_a_monitor_that_keeps_nothing_leaves_the_task_policy(tiny_zoo) -> None:
    """No keeping action: the goal is not reached (R2), so ε = 0 and the task policy itself."""
    _register_monitor(tiny_zoo.store, "a2", [-5.0] * 5)
    engine = InferenceEngine(tiny_zoo.store, goal_oracle=False)
    bounded = engine.act(ActRequest("particle", "a2", OBS, PARTNERS))
    task = engine.act(ActRequest("particle", "a2", OBS, PARTNERS, method="sl"))
    for b, t in zip(bounded, task, strict=True):
        np.testing.assert_allclose(b.probs, t.probs, atol=1e-12)


def test_without_a_monitor_the_bound_applies_everywhere_and_none_is_named(tiny_zoo) -> None:
    engine = InferenceEngine(tiny_zoo.store, goal_oracle=False)
    rows = engine.act(ActRequest("particle", "b3", OBS, PARTNERS))
    assert all(m.role != "monitor" for row in rows for m in row.models)
    # registered later: seen from the store's next generation on
    _register_monitor(tiny_zoo.store, "b3", [5.0] * 5)
    engine.refresh()
    rows = engine.act(ActRequest("particle", "b3", OBS, PARTNERS))
    assert any(m.role == "monitor" for m in rows[0].models)
