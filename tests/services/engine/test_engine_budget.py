"""aail_budget in the engine (`policy.regret_budget`, eqs. B1-B4): its policy is the task's and
AAIL's mixed as the equations say, the episode's state goes out and comes back, and every new
field is checked by name."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from zoo_fixtures import ZOO_ALPHA

from policy.blend import blend
from policy.maths import boltzmann
from policy.qnet import QNetSpec, qnet_from_safetensors
from policy.regret_budget import (
    BUDGET_EPSILON_PER_ALPHA,
    DEFAULT_BUDGET_FRACTION,
    budget_rows,
    initial_budget,
)
from services.engine import ActRequest, InferenceEngine, InvalidRequest, PartnerSpec

PARTNERS = (PartnerSpec(1, goal="b3"),)


def _obs(rows: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    obs = rng.uniform(0, 1, (rows, 8))
    obs[:, [2, 3, 6, 7]] = rng.normal(0, 0.1, (rows, 4))
    return obs


def _request(obs: np.ndarray, **kwargs: object) -> ActRequest:
    return ActRequest(env="particle", ego_goal="a2", observations=obs, partners=PARTNERS, **kwargs)  # type: ignore[arg-type]


def _q(store, name: str, x_BD: np.ndarray) -> np.ndarray:
    """Q of network `name`@production on input rows, one torch forward (the reference)."""
    mv = store.resolve(f"{name}@production")
    net = qnet_from_safetensors(
        QNetSpec.from_json(mv.spec), store.load_weights(mv.name, mv.version)
    )
    with torch.no_grad():
        return net(torch.as_tensor(x_BD, dtype=torch.float32)).double().numpy()


def test_first_step_mixes_task_and_aail_as_eqs_b1_b4_say(tiny_zoo_store) -> None:
    engine = InferenceEngine(tiny_zoo_store)
    obs = _obs(256)
    budget = engine.act_columns(_request(obs, method="aail_budget", budget=0.3))
    sl = engine.act_columns(_request(obs, method="sl"))
    # two agents: the ego's task view and the partner's impact view are both (ego, partner)
    q_task = _q(tiny_zoo_store, "particle/task/a2", obs)
    q_impact = _q(tiny_zoo_store, "particle/impact/b3", obs)
    # AAIL bounded by R1 at every step (no goal-reached guard), ε = 8α; then eqs. B1-B4
    epsilon = BUDGET_EPSILON_PER_ALPHA * ZOO_ALPHA
    bounded = blend("aail_bounded", q_task, q_impact[:, None], ZOO_ALPHA, regret_bound=epsilon)
    total = initial_budget(sl.probs, q_task, 0.3)
    want = budget_rows(sl.probs, bounded.probs_BA, q_task, q_impact[:, None], np.zeros(256), total)
    # rows at a threshold of the rule (an action at R1's edge max Q - ε, a cost near 0, a gain
    # near the cost) may fall either side in float32 arithmetic: left out
    edge = np.abs(q_task - (q_task.max(axis=1, keepdims=True) - epsilon)) < 1e-4
    cost, gain = want.cost_B, want.gain_B
    moved = np.abs(bounded.probs_BA - sl.probs).max(axis=1) > 1e-6  # where β matters at all
    ties = moved & (np.abs(gain - np.maximum(cost, 0.0)) < 1e-4)
    clear = np.asarray(~edge.any(axis=1) & ~ties)
    assert budget.budget_spent is not None and budget.budget_total is not None
    assert clear.sum() > 200
    np.testing.assert_allclose(budget.probs[clear], want.probs_BA[clear], atol=2e-5)
    np.testing.assert_allclose(budget.budget_spent[clear], want.spent_B[clear], atol=2e-5)
    np.testing.assert_allclose(budget.budget_total, total, rtol=2e-5, atol=1e-6)
    assert 0 < (budget.budget_spent > 0).sum() < 256  # some rows pay, some do not


def test_an_episode_carries_its_state_and_ends_as_sl_when_spent(tiny_zoo_store) -> None:
    engine = InferenceEngine(tiny_zoo_store)
    obs = _obs(1, seed=3)
    first = engine.act(_request(obs, method="aail_budget"))[0]
    sl = engine.act(_request(obs, method="sl"))[0]
    assert first.budget_total is not None and first.budget_spent is not None
    q_task = _q(tiny_zoo_store, "particle/task/a2", obs)
    expected = initial_budget(np.asarray([sl.probs]), q_task, DEFAULT_BUDGET_FRACTION)[0]
    assert first.budget_total == pytest.approx(expected, rel=2e-5)
    spent = engine.act(_request(obs, method="aail_budget", budget_spent=[1.0], budget_total=[1.0]))[
        0
    ]
    np.testing.assert_allclose(spent.probs, sl.probs, atol=1e-9)  # nothing left: the task's
    assert spent.budget_spent == 1.0 and spent.budget_total == 1.0


def test_regret_bound_sets_the_per_step_epsilon(tiny_zoo_store) -> None:
    engine = InferenceEngine(tiny_zoo_store)
    obs = _obs(32, seed=8)
    q_task = _q(tiny_zoo_store, "particle/task/a2", obs)
    zero = engine.act_columns(_request(obs, method="aail_budget", regret_bound=0.0, budget=5.0))
    # ε = 0: only the task's best action(s) may take the blend's share, and they hold it all
    best = q_task >= q_task.max(axis=1, keepdims=True)
    sl = engine.act_columns(_request(obs, method="sl"))
    np.testing.assert_allclose(zero.probs[~best], sl.probs[~best], atol=1e-6)


def test_other_methods_answer_no_budget(tiny_zoo_store) -> None:
    engine = InferenceEngine(tiny_zoo_store)
    for method in ("aail", "aail_bounded", "sl", "nail"):
        columns = engine.act_columns(_request(_obs(2), method=method))
        assert columns.budget_spent is None and columns.budget_total is None
        assert engine.act(_request(_obs(1), method=method))[0].budget_total is None


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"method": "aail", "budget": 0.1}, "budget"),
        ({"method": "aail", "regret_bound": 0.1}, "regret_bound"),
        ({"method": "aail_bounded", "budget_spent": [0.0], "budget_total": [1.0]}, "budget_spent"),
        ({"budget": -0.1}, "budget"),
        ({"budget": float("nan")}, "budget"),
        ({"budget": "0.1"}, "budget"),
        ({"budget_spent": [0.0]}, "budget_total"),
        ({"budget_total": [1.0]}, "budget_spent"),
        ({"budget_spent": [0.0, 0.0], "budget_total": [1.0]}, "budget_spent"),
        ({"budget_spent": [0.0], "budget_total": [-1.0]}, "budget_total"),
        ({"budget_spent": [float("inf")], "budget_total": [1.0]}, "budget_spent"),
        ({"budget_spent": ["x"], "budget_total": [1.0]}, "budget_spent"),
    ],
)
def test_bad_budget_fields_are_refused_by_name(tiny_zoo_store, kwargs, field) -> None:
    engine = InferenceEngine(tiny_zoo_store)
    kwargs = {"method": "aail_budget", **kwargs}
    with pytest.raises(InvalidRequest) as err:
        engine.act(_request(_obs(1), **kwargs))
    assert err.value.field == field


def test_budget_state_is_per_row_in_a_batch(tiny_zoo_store) -> None:
    engine = InferenceEngine(tiny_zoo_store)
    obs = _obs(3, seed=5)
    spent, total = np.array([0.0, 0.5, 2.0]), np.array([1.0, 0.5, 2.0])
    batch = engine.act_columns(
        _request(obs, method="aail_budget", budget_spent=spent, budget_total=total)
    )
    for b in range(3):
        single = engine.act(
            _request(
                obs[b : b + 1],
                method="aail_budget",
                budget_spent=spent[b : b + 1],
                budget_total=total[b : b + 1],
            )
        )[0]
        np.testing.assert_allclose(batch.probs[b], single.probs, atol=1e-12)
        assert batch.budget_spent is not None
        assert batch.budget_spent[b] == pytest.approx(single.budget_spent)
    np.testing.assert_array_equal(batch.budget_total, total)
    assert boltzmann(np.zeros((1, 5)), 1.0).shape == (1, 5)


def test_aail_budget_asks_the_environment_nothing(tiny_zoo_store, monkeypatch) -> None:
    """No oracle: the answers are the same where the domain cannot tell whether the ego's goal
    is reached or kept (both None), and neither is even asked."""
    from envs.particle.domain import PARTICLE

    engine = InferenceEngine(tiny_zoo_store)
    obs = _obs(16, seed=11)
    before = engine.act_columns(_request(obs, method="aail_budget"))

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("aail_budget asked the environment")

    monkeypatch.setattr(type(PARTICLE), "goal_reached", refuse)
    monkeypatch.setattr(type(PARTICLE), "goal_kept", refuse)
    after = engine.act_columns(_request(obs, method="aail_budget"))
    np.testing.assert_array_equal(before.probs, after.probs)
    np.testing.assert_array_equal(before.budget_spent, after.budget_spent)
