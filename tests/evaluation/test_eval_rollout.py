"""The vectorised episode runner: sampling, pairing of methods, and a naive-loop reference."""

from __future__ import annotations

import numpy as np
import pytest

from envs.particle.env import ParticleCoexistenceEnv
from envs.particle.goals import goal_index
from envs.particle.scenarios import start_states
from envs.particle.scripted import scripted_actions
from evaluation.backend import Answer, ModelRecord
from evaluation.config import Scenario
from evaluation.rollout import Cell, run_cells
from services.engine import ActRequest

RECORD = ModelRecord("particle/task/x", 1, "0" * 64, "task")


class FakeBackend:
    """Policies computed locally; records every request. `policy(request) -> probs (B, 5)`."""

    description = "fake"

    def __init__(self, policy: object) -> None:
        self.policy = policy
        self.requests: list[ActRequest] = []

    def probs(self, request: ActRequest) -> tuple[np.ndarray, set[ModelRecord]]:
        self.requests.append(request)
        return self.policy(request), {RECORD}  # type: ignore[operator]

    def answer(self, request: ActRequest) -> Answer:
        probs, models = self.probs(request)
        if request.method != "aail_budget":
            return Answer(probs, models)
        # a budget state that counts the steps: what the rollout must carry back
        rows = len(request.observations)
        spent = np.zeros(rows) if request.budget_spent is None else request.budget_spent
        value = np.zeros(rows) if request.budget_value is None else request.budget_value
        return Answer(
            probs, models, np.asarray(spent) + 1.0, np.full(rows, 100.0), np.asarray(value) - 1.0
        )

    def has_models(self, request: ActRequest) -> bool:
        return request.method != "jl"


def scripted_policy(request: ActRequest) -> np.ndarray:
    """One-hot of the scripted straight-to-target action of the requesting agent."""
    obs = np.asarray(request.observations, dtype=np.float64)
    state_BN4 = obs.reshape(obs.shape[0], -1, 4)
    goals_BN = np.full(state_BN4.shape[:2], goal_index(request.ego_goal))
    actions_B = scripted_actions(state_BN4, goals_BN)[:, 0]
    return np.eye(5)[actions_B]


def uniform_policy(request: ActRequest) -> np.ndarray:
    return np.full((len(request.observations), 5), 0.2)


def test_every_method_sees_the_same_starts_and_random_numbers() -> None:
    scenario = Scenario("s", "a2", ("b3",), 5, 11)
    backend = FakeBackend(uniform_policy)  # every "method" is the same policy here
    cells = [Cell(scenario, m) for m in ("sl", "nail", "aail")]
    out = run_cells(backend, cells, max_steps=30, seed=3)
    starts = start_states(11, 5, 2)
    first = {r.method: np.asarray(r.observations) for r in backend.requests[:3]}
    for obs in first.values():
        np.testing.assert_allclose(obs, starts.reshape(5, 8), rtol=0, atol=1e-6)
    a, b, c = out.results
    for other in (b, c):
        np.testing.assert_array_equal(a.returns_EN, other.returns_EN)
        np.testing.assert_array_equal(a.length_E, other.length_E)
        np.testing.assert_array_equal(a.trajectory_TN4, other.trajectory_TN4)
    np.testing.assert_allclose(a.trajectory_TN4[0], starts[0])
    assert {alias for alias, _ in out.models} == {"production", "partners"}


def test_matches_a_naive_env_loop() -> None:
    scenario = Scenario("s", "c", ("c4", "b3"), 3, 5)
    backend = FakeBackend(scripted_policy)
    [result] = run_cells(backend, [Cell(scenario, "aail")], max_steps=60, seed=0).results
    starts = start_states(5, 3, 3)
    for e in range(3):
        env = ParticleCoexistenceEnv(goals=scenario.goals, max_steps=60)
        env.reset(options={"state": starts[e]})
        goals_N = np.array([goal_index(g) for g in scenario.goals])
        returns, length = np.zeros(3), 0
        infos: dict[str, dict[str, object]] = {}
        while env.agents:
            acts = scripted_actions(env.state().reshape(3, 4)[None], goals_N[None])[0]
            _, rewards, _, _, infos = env.step({a: int(acts[i]) for i, a in enumerate(env.agents)})
            returns += [rewards[a] for a in env.possible_agents]
            length += 1
        np.testing.assert_allclose(result.returns_EN[e], returns, rtol=1e-9)
        assert result.length_E[e] == length
        success = [infos[a]["in_target"] for a in env.possible_agents]
        assert result.success_EN[e].tolist() == success
        assert bool(result.solved_E[e]) == (length < 60)


def test_finished_episodes_are_not_sent_again() -> None:
    scenario = Scenario("s", "c", ("c",), 8, 2)
    backend = FakeBackend(scripted_policy)
    out = run_cells(backend, [Cell(scenario, "sl")], max_steps=80, seed=0)
    ego_rows = [len(r.observations) for r in backend.requests if r.alias == "production"]
    assert ego_rows == sorted(ego_rows, reverse=True)
    assert sum(ego_rows) == int(out.results[0].length_E.sum())
    assert out.backend_calls == len(backend.requests)


def test_cells_must_share_an_agent_count() -> None:
    two = Scenario("two", "a2", ("b3",), 2, 1)
    three = Scenario("three", "a2", ("b3", "c"), 2, 1)
    with pytest.raises(ValueError, match="one agent count"):
        run_cells(
            FakeBackend(uniform_policy), [Cell(two, "sl"), Cell(three, "sl")], max_steps=5, seed=0
        )
    with pytest.raises(ValueError, match="at least one cell"):
        run_cells(FakeBackend(uniform_policy), [], max_steps=5, seed=0)


def test_an_aail_budget_episode_carries_its_budget_state_step_to_step() -> None:
    scenario = Scenario("s", "a2", ("b3",), 4, 11)
    backend = FakeBackend(uniform_policy)
    run_cells(backend, [Cell(scenario, "aail_budget")], max_steps=6, seed=3, budget=0.2)
    ego = [r for r in backend.requests if r.method == "aail_budget"]
    first = ego[0]  # the first step sends no state
    assert first.budget_spent is None and first.budget_total is None and first.budget_value is None
    for t, request in enumerate(ego[1:], start=1):
        assert request.budget == 0.2
        np.testing.assert_array_equal(request.budget_spent, np.full(4, float(t)))
        np.testing.assert_array_equal(request.budget_total, np.full(4, 100.0))
        np.testing.assert_array_equal(request.budget_value, np.full(4, -float(t)))


@pytest.mark.parametrize("name", ["idle", "scripted", "eps_0.3", "hot", "switching", "same"])
def test_partner_types_act_as_their_table_says(name: str) -> None:
    from evaluation.partner_types import SWITCH_STEP, partner_type

    scenario = Scenario("s", "a2", ("e0",), 6, 11)
    backend = FakeBackend(scripted_policy)
    out = run_cells(
        backend, [Cell(scenario, "sl")], max_steps=30, seed=3, partner_type=partner_type(name)
    )
    trajectory = out.results[0].trajectory_TN4
    partner_calls = [r for r in backend.requests if r.ego_goal != "a2"]
    if name == "idle":  # rests: damping only, from a standing start it never moves
        np.testing.assert_allclose(
            trajectory[:, 1, :2], np.broadcast_to(trajectory[0, 1, :2], trajectory[:, 1, :2].shape)
        )
        assert not partner_calls
    elif name == "scripted":  # no network asked; it heads for e0 (row 0) on its own
        assert not partner_calls
        assert out.results[0].success_EN[:, 1].mean() > 0.5 or out.results[0].length_E.max() == 30
    elif name == "switching":  # its goal changes after SWITCH_STEP steps, to an untold one
        goals = {r.ego_goal for r in partner_calls[SWITCH_STEP:]}
        assert {r.ego_goal for r in partner_calls[:SWITCH_STEP]} == {"e0"}
        assert goals - {"e0"}
    else:
        alias = "production" if name == "same" else "partners"
        assert partner_calls and {r.alias for r in partner_calls} == {alias}
