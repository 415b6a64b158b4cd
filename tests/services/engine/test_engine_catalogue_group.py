"""services.engine: a request with a partner given as a goal distribution is served from every
goal's stacked group unless its own group is stacked (or small and asked for again): the
answers are the same, bit for bit, whichever group served them (module docstring, "Goal
distributions")."""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
import safetensors.numpy
from session_zoo import random_observation, session_zoo_template
from zoo_fixtures import PAIR_SPEC

from envs.particle.goals import GOAL_IDS
from model_store import impact_model_name, task_model_name
from model_store.entities import Lineage
from model_store.sql import SqlModelStore
from model_store.testing import qnet_spec, qnet_tensors
from services.engine import ActRequest, InferenceEngine, PartnerSpec
from services.sessions import Observed, Session, SessionPartner, SessionSettings


@pytest.fixture
def store(tmp_path_factory: pytest.TempPathFactory) -> Iterator[SqlModelStore]:
    """Every goal's task and impact network (the session zoo)."""
    with SqlModelStore(f"sqlite:///{session_zoo_template(tmp_path_factory)}") as zoo:
        yield zoo


def _request(obs: np.ndarray, partners: tuple[PartnerSpec, ...], **pins: int) -> ActRequest:
    versions = {task_model_name("particle", "a2"): v for v in pins.values()}
    return ActRequest("particle", "a2", obs, partners, method="aail", seed=4, versions=versions)


def _spread(goals: tuple[str, ...], rng: np.random.Generator) -> dict[str, float]:
    weights = rng.random(len(goals)) + 0.05
    return dict(zip(goals, (weights / weights.sum()).tolist(), strict=True))


def test_a_small_distribution_is_served_by_every_goal_then_by_its_own_group(store) -> None:
    """First request: every goal's group; the second stacks the request's own (2 networks);
    the third finds it stacked. The three answers are equal."""
    engine = InferenceEngine(store)
    rng = np.random.default_rng(0)
    obs = np.stack([random_observation(rng) for _ in range(3)])
    request = _request(obs, (PartnerSpec(1, goal_probs={"b3": 0.7, "d1": 0.3}),))
    answers, served = [], []
    for _ in range(3):
        before = engine.stats.snapshot()
        answers.append(engine.act(request))
        after = engine.stats
        served.append(
            (
                after.catalogue_group_acts - before.catalogue_group_acts,
                after.stack_misses - before.stack_misses,
            )
        )
    assert served == [(1, 1), (0, 1), (0, 0)]  # every goal's group, its own made, found
    assert answers[0] == answers[1] == answers[2]
    assert [m.goal for m in answers[0][0].models] == ["a2", "b3", "d1"]


def test_a_large_distribution_stays_on_every_goals_group(store) -> None:
    """Two partners over 12 goals each: every request is served by every goal's group (its
    own would rarely pay back its stacking) and answers as the request's own group does (a
    pinned version takes that path)."""
    engine = InferenceEngine(store)
    rng = np.random.default_rng(1)
    obs = np.stack([random_observation(rng, n_agents=3) for _ in range(2)])
    partners = (
        PartnerSpec(1, goal_probs=_spread(GOAL_IDS[:12], rng)),
        PartnerSpec(2, goal_probs=_spread(GOAL_IDS[10:22], rng)),
    )
    first, second = engine.act(_request(obs, partners)), engine.act(_request(obs, partners))
    assert engine.stats.catalogue_group_acts == 2
    own = engine.act(_request(obs, partners, pin=1))  # the pinned task version is the alias's
    assert engine.stats.catalogue_group_acts == 2
    assert first == second
    for a, b in zip(first, own, strict=True):
        assert (a.probs, a.action, a.partner_weights) == (b.probs, b.action, b.partner_weights)
        assert (a.task_entropy, a.task_weight) == (b.task_entropy, b.task_weight)
        assert a.models[1:] == b.models[1:]  # the impact networks, in the partners' order


def test_announced_goals_alone_and_the_numpy_forward_keep_their_own_group(store) -> None:
    engine, numpy_engine = InferenceEngine(store), InferenceEngine(store, numpy_forward=True)
    obs = random_observation(np.random.default_rng(2), n_agents=3)[None]
    engine.act(_request(obs, (PartnerSpec(1, goal="b3"), PartnerSpec(2, goal="e0"))))
    numpy_engine.act(_request(obs, (PartnerSpec(1, goal_probs={"b3": 0.5, "c1": 0.5}),)))
    assert engine.stats.catalogue_group_acts == numpy_engine.stats.catalogue_group_acts == 0


@pytest.mark.parametrize("announced_first", [True, False])
def test_an_announced_partner_beside_a_distribution(store, announced_first: bool) -> None:
    """Every goal's group serves the announced partner's goal on its own row too: the answer
    is the request's own group's (pinned), models in the partners' order."""
    engine = InferenceEngine(store)
    rng = np.random.default_rng(7)
    obs = np.stack([random_observation(rng, n_agents=4) for _ in range(2)])
    spread = PartnerSpec(2, goal_probs=_spread(GOAL_IDS[5:17], rng))
    announced = (PartnerSpec(1, goal="e0"), PartnerSpec(3, goal="b3"))
    partners = (*announced, spread) if announced_first else (spread, *announced)
    first = engine.act(_request(obs, partners))
    assert engine.stats.catalogue_group_acts == 1
    own = engine.act(_request(obs, partners, pin=1))
    assert engine.stats.catalogue_group_acts == 1
    for a, b in zip(first, own, strict=True):
        assert (a.probs, a.action, a.partner_weights) == (b.probs, b.action, b.partner_weights)
        assert a.models[1:] == b.models[1:]
    goals = [m.goal for m in first[0].models[1:]]
    assert goals == [g for p in partners for g in (p.goal_probs or [p.goal])]


def test_a_missing_network_of_the_catalogue_is_not_looked_up_again_until_the_store_changes(
    tiny_zoo, monkeypatch
) -> None:
    """The tiny zoo holds six goals' impact networks: distributions over two of them are
    answered from their own group; every goal's group is asked for once, and again only after
    a refresh that saw the store change."""
    engine = InferenceEngine(tiny_zoo.store)
    obs = np.random.default_rng(3).random((1, 8))
    resolve_group, catalogue_asked = engine.cache.resolve_group, []

    def counted(needs: Any, alias: str, pinned: Any, members: Any, domain: Any) -> Any:
        catalogue_asked.append(len(members) == 1 + len(GOAL_IDS))
        return resolve_group(needs, alias, pinned, members, domain)

    monkeypatch.setattr(engine.cache, "resolve_group", counted)

    def act(goals: dict[str, float]) -> int:
        """Whether this act asked for every goal's group."""
        catalogue_asked.clear()
        engine.act(_request(obs, (PartnerSpec(1, goal_probs=goals),)))
        return sum(catalogue_asked)

    assert act({"b3": 0.5, "c1": 0.5}) == 1  # missing: answered from its own group
    assert act({"c1": 0.5, "b3": 0.5}) == 0  # another request shape: not asked again
    tiny_zoo.register("particle/impact/e0", "impact", ("e0",), PAIR_SPEC, 77)  # a change
    engine.refresh()
    assert engine.stats.refreshes == 1
    assert act({"b3": 0.5, "e0": 0.5}) == 1  # asked again (and still missing)
    assert engine.stats.catalogue_group_acts == 0


def test_a_top_goal_session_acts_as_the_act_with_its_beliefs(store) -> None:
    """Every partner inferred, at most 3 goals each: each step (served by every goal's group,
    a new goal set at each step) equals `engine.act` with the same goal distributions."""
    from policy.belief import blend_goal_probs

    engine = InferenceEngine(store)
    partners = (SessionPartner(1, infer=True), SessionPartner(2, infer=True))
    settings = SessionSettings("particle", "a2", partners, seed=5, blend_max_goals=3)
    session = Session(engine, settings, prefetch=False)
    rng = np.random.default_rng(4)
    for t in range(4):
        obs = random_observation(rng, n_agents=3)
        observed = [Observed(1, t % 5), Observed(2, (2 * t) % 5)] if t else []
        answer = session.step(obs, observed)
        # the goal distributions of the beliefs the step committed
        goal_probs = [blend_goal_probs(row, GOAL_IDS, 1.0, 3) for row in session._log_belief_PG]
        expected = engine.act(
            ActRequest(
                "particle",
                "a2",
                obs[None],
                tuple(PartnerSpec(j + 1, goal_probs=g) for j, g in enumerate(goal_probs)),
                seed=5 + t,
            )
        )[0]
        assert answer.result == expected
        assert sum(m.role == "impact" for m in answer.result.models) == 6


def test_every_goals_group_follows_a_moved_alias(tmp_path, tmp_path_factory) -> None:
    """Hot reload: after `production` of one impact network moves, every goal's group serves
    its new version, and the answer is the request's own group's (pinned task network)."""
    path = tmp_path / "models.db"
    shutil.copy(session_zoo_template(tmp_path_factory), path)
    with SqlModelStore(f"sqlite:///{path}") as zoo:
        engine = InferenceEngine(zoo)
        rng = np.random.default_rng(6)
        obs = random_observation(rng)[None]
        partners = (PartnerSpec(1, goal_probs=_spread(GOAL_IDS[:12], rng)),)
        before = engine.act(_request(obs, partners))[0]
        spec = qnet_spec(obs_dim=8, n_actions=5, hidden=(16,))
        moved = impact_model_name("particle", GOAL_IDS[3])
        zoo.register_version(
            moved,
            spec=spec,
            weights=safetensors.numpy.save(qnet_tensors(spec, seed=31)),
            lineage=Lineage(config={"alpha": 0.05}, seed=31, registered_by="pytest"),
            aliases=("production",),
        )
        assert engine.refresh()
        after = engine.act(_request(obs, partners))[0]
        own = engine.act(_request(obs, partners, pin=1))[0]
    assert engine.stats.catalogue_group_acts == 2
    assert {m.name: m.version for m in after.models}[moved] == 2
    assert {m.name: m.version for m in before.models}[moved] == 1
    assert (after.probs, after.partner_weights) == (own.probs, own.partner_weights)
    assert after.probs != before.probs
