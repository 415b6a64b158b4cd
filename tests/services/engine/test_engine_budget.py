"""aail_budget in the engine (`policy.regret_budget`, eqs. B1-B4): its policy is AAIL's or the
task's as the equations say, the episode's state goes out and comes back, and every new field is
checked by name."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from zoo_fixtures import ZOO_ALPHA

from policy.blend import blend
from policy.maths import boltzmann, soft_value
from policy.qnet import QNetSpec, qnet_from_safetensors
from policy.regret_budget import DEFAULT_BUDGET_PER_ALPHA, budget_rows
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


def test_a_step_follows_aail_or_the_task_as_eqs_b1_b4_say(tiny_zoo_store) -> None:
    engine = InferenceEngine(tiny_zoo_store)
    rows = 256
    obs = _obs(rows)
    rng = np.random.default_rng(4)
    total = np.full(rows, 0.3)
    spent = rng.uniform(0.0, 0.4, rows)  # some rows spent already
    # two agents: the ego's task view and the partner's impact view are both (ego, partner)
    q_task = _q(tiny_zoo_store, "particle/task/a2", obs)
    q_impact = _q(tiny_zoo_store, "particle/impact/b3", obs)
    value = soft_value(q_task, ZOO_ALPHA)
    last = value + rng.normal(0.0, 0.1, rows)  # what the ego's value was a step ago
    budget = engine.act_columns(
        _request(
            obs, method="aail_budget", budget_spent=spent, budget_total=total, budget_value=last
        )
    )
    sl = engine.act_columns(_request(obs, method="sl"))
    aail = blend("aail", q_task, q_impact[:, None], ZOO_ALPHA)
    want = budget_rows(sl.probs, aail.probs_BA, q_task, value, spent, total, last)
    # rows where the spend after B2 is within float32 rounding of B may fall either side
    charged = np.maximum(spent + last - value, 0.0)
    clear = np.abs(charged - total) > 1e-4
    assert budget.budget_spent is not None and budget.budget_value is not None
    assert clear.sum() > 200 and 0 < want.blend_B[clear].mean() < 1
    np.testing.assert_allclose(budget.probs[clear], want.probs_BA[clear], atol=2e-5)
    np.testing.assert_allclose(budget.budget_spent[clear], want.spent_B[clear], atol=2e-5)
    np.testing.assert_allclose(budget.budget_value, value, atol=2e-5)
    np.testing.assert_array_equal(budget.budget_total, total)


def test_an_episode_carries_its_state_and_ends_as_sl_when_spent(tiny_zoo_store) -> None:
    engine = InferenceEngine(tiny_zoo_store)
    obs = _obs(1, seed=3)
    first = engine.act(_request(obs, method="aail_budget"))[0]
    sl = engine.act(_request(obs, method="sl"))[0]
    aail = engine.act(_request(obs, method="aail"))[0]
    assert first.budget_total == pytest.approx(DEFAULT_BUDGET_PER_ALPHA * ZOO_ALPHA)
    q_task = _q(tiny_zoo_store, "particle/task/a2", obs)
    assert first.budget_value == pytest.approx(soft_value(q_task, ZOO_ALPHA)[0], abs=2e-5)
    # the first step loses nothing yet and follows AAIL; it spends what AAIL is expected to cost
    np.testing.assert_allclose(first.probs, aail.probs, atol=1e-9)
    cost = float(((np.asarray(sl.probs) - np.asarray(aail.probs)) * q_task[0]).sum())
    assert first.budget_spent == pytest.approx(max(cost, 0.0), abs=2e-5)
    carried = {"budget_spent": [1.0], "budget_total": [1.0], "budget_value": [first.budget_value]}
    spent = engine.act(_request(obs, method="aail_budget", **carried))[0]
    np.testing.assert_allclose(spent.probs, sl.probs, atol=1e-9)  # nothing left: the task's
    assert spent.budget_spent == 1.0 and spent.budget_total == 1.0


def test_the_budget_parameter_is_the_episodes_budget(tiny_zoo_store) -> None:
    engine = InferenceEngine(tiny_zoo_store)
    obs = _obs(4, seed=8)
    zero = engine.act_columns(_request(obs, method="aail_budget", budget=0.0))
    sl = engine.act_columns(_request(obs, method="sl"))
    np.testing.assert_allclose(zero.probs, sl.probs, atol=1e-9)  # no budget: the task policy
    some = engine.act_columns(_request(obs, method="aail_budget", budget=0.7))
    np.testing.assert_array_equal(some.budget_total, np.full(4, 0.7))


def test_other_methods_answer_no_budget(tiny_zoo_store) -> None:
    engine = InferenceEngine(tiny_zoo_store)
    for method in ("aail", "aail_bounded", "sl", "nail"):
        columns = engine.act_columns(_request(_obs(2), method=method))
        assert columns.budget_spent is None and columns.budget_total is None
        assert columns.budget_value is None
        assert engine.act(_request(_obs(1), method=method))[0].budget_total is None


STATE = {"budget_spent": [0.0], "budget_total": [1.0], "budget_value": [-0.5]}


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"method": "aail", "budget": 0.1}, "budget"),
        ({"method": "aail", "regret_bound": 0.1}, "regret_bound"),
        ({"regret_bound": 0.1}, "regret_bound"),
        ({"method": "aail_bounded", "budget_spent": [0.0], "budget_total": [1.0]}, "budget_spent"),
        ({"method": "sl", "budget_value": [0.0]}, "budget_value"),
        ({"budget": -0.1}, "budget"),
        ({"budget": float("nan")}, "budget"),
        ({"budget": "0.1"}, "budget"),
        ({"budget_spent": [0.0]}, "budget_total"),
        ({"budget_total": [1.0]}, "budget_spent"),
        ({"budget_spent": [0.0], "budget_total": [1.0]}, "budget_value"),
        ({"budget_value": [-1.0]}, "budget_spent"),
        ({**STATE, "budget_spent": [0.0, 0.0]}, "budget_spent"),
        ({**STATE, "budget_total": [-1.0]}, "budget_total"),
        ({**STATE, "budget_spent": [float("inf")]}, "budget_spent"),
        ({**STATE, "budget_spent": ["x"]}, "budget_spent"),
        ({**STATE, "budget_value": [float("nan")]}, "budget_value"),
        ({**STATE, "budget_value": [0.0, 1.0]}, "budget_value"),
        ({**STATE, "budget_value": "x"}, "budget_value"),
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
    value = np.array([-0.2, -0.4, -1.0])
    batch = engine.act_columns(
        _request(
            obs, method="aail_budget", budget_spent=spent, budget_total=total, budget_value=value
        )
    )
    for b in range(3):
        single = engine.act(
            _request(
                obs[b : b + 1],
                method="aail_budget",
                budget_spent=spent[b : b + 1],
                budget_total=total[b : b + 1],
                budget_value=value[b : b + 1],
            )
        )[0]
        np.testing.assert_allclose(batch.probs[b], single.probs, atol=1e-12)
        assert batch.budget_spent is not None and batch.budget_value is not None
        assert batch.budget_spent[b] == pytest.approx(single.budget_spent)
        assert batch.budget_value[b] == pytest.approx(single.budget_value)
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
    np.testing.assert_array_equal(before.budget_value, after.budget_value)
