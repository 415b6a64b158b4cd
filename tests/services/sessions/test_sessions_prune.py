"""Goal pruning in sessions (`belief.prune_below` τ, `belief.prune_error` δ): each step's belief
is within δ (total variation) of the exact update of the belief the session held, with and
without the likelihood table scored ahead; a δ no bound meets scores every goal and gives the
unpruned session's beliefs; the act blends only the goals at or above τ while those below hold at most δ; pruning off is the
default."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest
from session_zoo import partner_action, random_observation, session_zoo_template

from envs.particle.goals import GOAL_IDS
from model_store.sql import SqlModelStore
from policy.belief import BeliefConfig, update_log_belief
from services.engine import InferenceEngine
from services.sessions import Observed, Session, SessionPartner, SessionSettings


@pytest.fixture(scope="module")
def engine(tmp_path_factory: pytest.TempPathFactory) -> Iterator[InferenceEngine]:
    with SqlModelStore(f"sqlite:///{session_zoo_template(tmp_path_factory)}") as store:
        yield InferenceEngine(store)


def settings(n_agents: int, belief: BeliefConfig) -> SessionSettings:
    partners = tuple(SessionPartner(i, infer=True) for i in range(1, n_agents))
    return SessionSettings("particle", "a2", partners, seed=3, belief=belief)


def episode(
    engine: InferenceEngine, n_agents: int, steps: int, seed: int
) -> tuple[list[np.ndarray], list[list[Observed]]]:
    """Random observations; partner p acts mostly as goal `GOAL_IDS[5 * p]` would (so the
    belief concentrates and pruning starts), switching goal halfway (so it must come back)."""
    rng = np.random.default_rng(seed)
    observations = [random_observation(rng, n_agents) for _ in range(steps)]
    observed: list[list[Observed]] = [[]]
    for t in range(1, steps):
        entries = []
        for p in range(1, n_agents):
            goal = GOAL_IDS[(5 * p + (7 if t > steps // 2 else 0)) % len(GOAL_IDS)]
            mostly = rng.random() < 0.8
            action = partner_action(engine, observations[t - 1], p, goal) if mostly else None
            entries.append(Observed(p, int(rng.integers(5)) if action is None else action))
        observed.append(entries)
    return observations, observed


def tv(log_p: np.ndarray, log_q: np.ndarray) -> np.ndarray:
    return 0.5 * np.abs(np.exp(log_p) - np.exp(log_q)).sum(axis=-1)


@pytest.mark.parametrize("ahead", [True, False])
@pytest.mark.parametrize("n_agents", [2, 4])
def test_each_step_is_within_delta_of_the_exact_update(
    engine: InferenceEngine, ahead: bool, n_agents: int
) -> None:
    belief = BeliefConfig(forgetting=0.95, floor=1e-4, prune_below=0.01, prune_error=0.05)
    session = Session(engine, settings(n_agents, belief), prefetch=ahead)
    observations, observed = episode(engine, n_agents, 40, seed=n_agents)
    prior = session.checked.log_prior_PG
    pruned_before = engine.stats.pruned_updates
    largest = 0.0
    for t, (obs, entries) in enumerate(zip(observations, observed, strict=True)):
        held = session.export_state().log_belief_PG
        session.step(obs.tolist(), entries)
        session.prepare_next()
        got = session.export_state().log_belief_PG
        if t == 0:
            continue
        lik = engine.goal_log_likelihoods(
            "particle",
            observations[t - 1],
            [e.index for e in entries],
            [int(e.action or 0) for e in entries],
            noise=belief.noise,  # the session's likelihood: its policy mixed with uniform noise
        )
        exact = update_log_belief(held, lik, prior, belief)
        distance = tv(got, exact)
        assert np.all(distance <= belief.prune_error + 1e-12), (t, distance)
        largest = max(largest, float(distance.max()))
    assert engine.stats.pruned_updates > pruned_before  # pruning did happen
    assert largest > 0  # and it changed the numbers: the test can see a difference


def test_a_delta_no_bound_meets_scores_every_goal(engine: InferenceEngine) -> None:
    """δ below every bound: each row is rescored, the beliefs are the unpruned session's."""
    tight = BeliefConfig(floor=1e-4, prune_below=0.01, prune_error=1e-300)
    plain = BeliefConfig(floor=1e-4)
    pruning, exact = Session(engine, settings(3, tight)), Session(engine, settings(3, plain))
    observations, observed = episode(engine, 3, 25, seed=9)
    rescored = engine.stats.pruned_rescored
    for obs, entries in zip(observations, observed, strict=True):
        for session in (pruning, exact):
            session.step(obs.tolist(), entries)
            session.prepare_next()
        np.testing.assert_allclose(
            pruning.export_state().log_belief_PG, exact.export_state().log_belief_PG, atol=1e-12
        )
    assert engine.stats.pruned_rescored > rescored


def test_the_act_blends_only_the_goals_at_or_above_tau(engine: InferenceEngine) -> None:
    belief = BeliefConfig(floor=1e-4, prune_below=0.02, prune_error=0.2)
    session = Session(engine, settings(2, belief))
    observations, observed = episode(engine, 2, 20, seed=3)
    smallest = len(GOAL_IDS)
    for obs, entries in zip(observations, observed, strict=True):
        held = session.export_state().log_belief_PG[0]
        answer = session.step(obs.tolist(), entries)
        session.prepare_next()
        new = np.exp(session.export_state().log_belief_PG[0])
        blended = {m.goal for m in answer.result.models if m.role == "impact"}
        wanted = {g for g, p in zip(GOAL_IDS, new, strict=True) if p >= belief.prune_below}
        wanted.add(GOAL_IDS[int(np.argmax(new))])
        left_out = sum(p for g, p in zip(GOAL_IDS, new, strict=True) if g not in wanted)
        if left_out > belief.prune_error:  # too much left out: the whole belief
            wanted = set(GOAL_IDS)
        assert blended == wanted
        assert len(held) == len(GOAL_IDS)
        smallest = min(smallest, len(blended))
    assert smallest < len(GOAL_IDS)  # the belief concentrated: goals were left out


def test_pruning_is_off_by_default() -> None:
    assert BeliefConfig().prune_below == 0
