"""A session's default blend mixes the impact networks of EVERY goal by the belief: the exact
expected impact Q, one stacked group and one row layout reused at every step (nothing rebuilt as
the belief moves), the same answer as `/v1/act` with that distribution, bit for bit. Also the
partner-index check a step makes on the stored observation."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest
from session_zoo import random_observation, session_zoo_template

from envs.particle.goals import GOAL_IDS
from model_store.sql import SqlModelStore
from policy.belief import (
    BeliefConfig,
    blend_goal_probs,
    initial_log_belief,
    prior_log_probs,
    update_log_belief,
)
from services.engine import ActRequest, InferenceEngine, InvalidRequest, PartnerSpec
from services.sessions import Observed, Session, SessionPartner, SessionSettings


@pytest.fixture(scope="module")
def engine(tmp_path_factory: pytest.TempPathFactory) -> Iterator[InferenceEngine]:
    with SqlModelStore(f"sqlite:///{session_zoo_template(tmp_path_factory)}") as store:
        yield InferenceEngine(store)


def test_defaults_blend_every_goal() -> None:
    settings = SessionSettings("particle", "a2", (SessionPartner(1, infer=True),))
    assert (settings.blend_mass, settings.blend_max_goals) == (1.0, None)


def test_a_default_step_is_the_act_with_the_whole_belief(engine: InferenceEngine) -> None:
    config = BeliefConfig()
    session = Session(
        engine, SessionSettings("particle", "a2", (SessionPartner(1, infer=True),), seed=3)
    )
    log_prior = prior_log_probs(GOAL_IDS)
    log_b = initial_log_belief(log_prior, config)
    rng, previous = np.random.default_rng(8), np.zeros(8)
    for t in range(4):
        obs = random_observation(rng)
        action = int(rng.integers(5))
        if t:
            lik = engine.goal_log_likelihoods(
                "particle", previous, [1], [action], noise=config.noise
            )
            log_b = update_log_belief(log_b[None], lik, log_prior[None], config)[0]
        goal_probs = blend_goal_probs(log_b, GOAL_IDS)
        assert list(goal_probs) == list(GOAL_IDS)
        expected = engine.act(
            ActRequest(
                "particle", "a2", obs[None], (PartnerSpec(1, goal_probs=goal_probs),), seed=3 + t
            )
        )[0]
        answer = session.step(obs, [Observed(1, action)] if t else [])
        assert answer.result == expected
        assert sum(m.role == "impact" for m in answer.result.models) == len(GOAL_IDS)
        previous = obs


def test_default_steps_reuse_one_group_and_layout(engine: InferenceEngine) -> None:
    """After the first two steps (likelihood group, act group) nothing is stacked, planned or
    laid out again, however the belief moves."""
    session = Session(
        engine,
        SessionSettings("particle", "b3", (SessionPartner(1, infer=True),), belief=BeliefConfig()),
    )
    rng = np.random.default_rng(2)
    session.step(random_observation(rng))
    session.step(random_observation(rng), [Observed(1, 0)])
    stats, plans = engine.stats.snapshot(), len(engine.plans)
    tops = set()
    for t in range(30):
        answer = session.step(random_observation(rng), [Observed(1, t % 5)])
        tops.add(answer.beliefs[0].top[0][0])
    assert len(tops) > 1  # the belief did move
    assert (engine.stats.stack_misses, engine.stats.loads) == (stats.stack_misses, stats.loads)
    assert engine.stats.stack_hits == stats.stack_hits + 2 * 30
    assert len(engine.plans) == plans


def test_a_truncated_blend_is_still_an_option(engine: InferenceEngine) -> None:
    settings = SessionSettings(
        "particle", "a2", (SessionPartner(1, infer=True),), blend_mass=0.5, blend_max_goals=2
    )
    answer = Session(engine, settings).step(np.zeros(8))
    assert sum(m.role == "impact" for m in answer.result.models) == 2  # uniform belief: 2 goals
    bad = SessionSettings(
        "particle",
        "a2",
        (SessionPartner(1, infer=True),),
        blend_max_goals=np.int64(0),  # type: ignore[arg-type]  # numpy ints are checked too
    )
    with pytest.raises(InvalidRequest) as err:
        Session(engine, bad)
    assert err.value.field == "belief.blend_max_goals"


def test_actions_are_judged_on_the_agents_of_the_stored_observation(
    engine: InferenceEngine,
) -> None:
    """New settings (an `Episode`'s) may add a partner the stored observation does not hold:
    its action there cannot be judged, and the step says so, changing nothing."""
    session = Session(engine, SessionSettings("particle", "a2", (SessionPartner(1, infer=True),)))
    session.step(np.full(8, 0.1))
    partners = (SessionPartner(1, infer=True), SessionPartner(2, infer=True))
    session.replace_settings(SessionSettings("particle", "a2", partners))
    before = session.snapshot()
    with pytest.raises(InvalidRequest, match="previous observation holds 2") as err:
        session.step(np.full(12, 0.1), [Observed(1, 0), Observed(2, 3)])
    assert err.value.field == "observed[1].index"
    assert session.snapshot() == before
    assert session.step(np.full(12, 0.1), [Observed(1, 0)]).beliefs[0].updates == 1
