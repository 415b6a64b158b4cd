"""The engine's one path on every request layout (single rows and batches, announced goals and
distributions, impact networks shared between partners, mixed architectures) against the
naive reference of tests/services/engine/test_engine_reference.py; the same errors and
counters; the plan cache's bound and generation; thread safety."""

from __future__ import annotations

import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, note, settings
from hypothesis import strategies as st

from services.engine import (
    DEFAULT_TEMPERATURE,
    ActRequest,
    InferenceEngine,
    InvalidRequest,
    PartnerSpec,
)
from services.engine.planning import PlanCache

sys.path.insert(0, str(Path(__file__).parent))
from test_engine_reference import _check_row, reference
from zoo_fixtures import PAIR_SPEC

GOALS = ("b3", "c1", "d4", "e0", "c")


@st.composite
def requests(draw) -> ActRequest:
    n_agents = draw(st.integers(1, 5))
    n_partners = draw(st.integers(0, n_agents - 1))
    indices = draw(st.permutations(range(1, n_agents)))[:n_partners]
    goals = draw(st.permutations(GOALS))
    partners = []
    for index, goal in zip(indices, goals, strict=False):
        if draw(st.booleans()):
            partners.append(PartnerSpec(index, goal=goal))
        else:  # a distribution; its other goal gets probability 0 half of the time
            p = draw(st.sampled_from([0.0, 0.3, 1.0]))
            partners.append(PartnerSpec(index, goal_probs={goal: 1.0 - p, "a2": p}))
    if draw(st.booleans()) and len(partners) > 1:  # one impact network for two partners
        partners[1] = PartnerSpec(partners[1].index, goal=partners[0].goal or "a2")
    obs = np.random.default_rng(draw(st.integers(0, 99))).normal(size=(1, 4 * n_agents))
    return ActRequest(
        "particle",
        draw(st.sampled_from(["a2", "b3", "c1"])),
        obs.astype(draw(st.sampled_from([np.float64, np.float32]))),
        tuple(partners),
        method=draw(st.sampled_from(["sl", "nail", "aail"])),
        temperature=draw(st.sampled_from([None, 0.05, 1.0])),
    )


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(request=requests())
def test_every_layout_matches_the_reference(tiny_zoo, request: ActRequest) -> None:
    note(repr(vars(request)))
    [result] = InferenceEngine(tiny_zoo.store).act(request)
    partners = [
        (p.index, {p.goal: 1.0} if p.goal else {g: q for g, q in (p.goal_probs or {}).items() if q})
        for p in request.partners
    ]
    # the request's temperature, else the task net's training α (none in the lineage: default)
    lineage_alpha = DEFAULT_TEMPERATURE if request.ego_goal == tiny_zoo.no_alpha_task else None
    alpha = request.temperature or lineage_alpha or tiny_zoo.alpha
    ref = reference(
        tiny_zoo.store, request.observations[0], request.ego_goal, partners, request.method, alpha
    )
    _check_row(result, ref)
    assert type(result.probs) is list and all(type(p) is float for p in result.probs)


def test_same_errors_and_counters(tiny_zoo) -> None:
    huge = np.full((1, 8), 3e38)  # finite in float32, the Q-values are not
    engine = InferenceEngine(tiny_zoo.store)
    for goal in ("a2", "b3", "a2"):
        engine.act(ActRequest("particle", goal, huge / 1e38, (PartnerSpec(1, goal="c1"),)))
    for obs in (huge, np.repeat(huge, 3, axis=0)):  # one row or a batch: the same error
        with pytest.raises(InvalidRequest) as err:
            engine.act(ActRequest("particle", "a2", obs, (PartnerSpec(1, goal="c1"),)))
        assert (err.value.field, err.value.message) == (
            "observations",
            "values so large that the Q-values overflow",
        )
    stats = engine.stats.snapshot()
    assert (stats.requests, stats.rows, stats.errors) == (3, 3, 2)
    assert (stats.stack_misses, stats.loads) == (2, 3)  # two groups, three networks


def test_the_plan_cache_is_bounded(tiny_zoo) -> None:
    """A cache too small for a request's plan and layout forgets and makes them again: the
    same answers, never more entries than its capacity; a large one makes them once."""
    obs = np.random.default_rng(3).random((1, 20))

    def acts(engine: InferenceEngine, sizes: list[int]) -> list[Any]:
        answers = []
        for i in (1, 2, 3, 4):  # four layouts of one stacked group
            partners = (PartnerSpec(i, goal="b3"),)
            answers.append(engine.act(ActRequest("particle", "a2", obs, partners, seed=0)))
            sizes.append(len(engine.plans))
        return answers

    sizes: list[int] = []
    small = InferenceEngine(tiny_zoo.store, plans=PlanCache(capacity=3))
    rounds = [acts(small, sizes) for _ in range(2)]
    assert rounds[0] == rounds[1] and max(sizes) <= 3
    large = InferenceEngine(tiny_zoo.store)
    assert acts(large, sizes) == rounds[0]
    grown = len(large.plans)
    assert acts(large, sizes) == rounds[0] and len(large.plans) == grown  # nothing new made


def test_a_store_generation_starts_an_empty_plan_cache(tiny_zoo) -> None:
    """The cache's one rule: what it holds belongs to the store generation it was made in."""
    plans = PlanCache()
    engine = InferenceEngine(tiny_zoo.store, plans=plans)
    obs = np.random.default_rng(4).random((1, 12))
    request = ActRequest("particle", "a2", obs, (PartnerSpec(1, goal="b3"),), seed=0)
    first = engine.act(request)
    before = plans.at(engine.cache.generation)
    assert len(before) > 0
    tiny_zoo.register("particle/impact/e0", "impact", ("e0",), PAIR_SPEC, 77)  # a change
    engine.refresh()
    assert engine.cache.generation == 1
    assert engine.act(request) == first
    assert plans.at(engine.cache.generation) is not before and len(plans) == len(before)


def test_concurrent_requests_match_sequential_ones(tiny_zoo) -> None:
    engine = InferenceEngine(tiny_zoo.store)
    rng = np.random.default_rng(4)
    requests = [
        ActRequest(
            "particle",
            "a2",
            rng.random((1, 20)),
            (PartnerSpec(1 + k % 4, goal="b3"), PartnerSpec(1 + (k + 1) % 4, goal="d4")),
            method=("sl", "nail", "aail")[k % 3],
            seed=k,
        )
        for k in range(120)
    ]
    sequential = [engine.act(r) for r in requests]
    with ThreadPoolExecutor(4) as pool:
        concurrent = list(pool.map(InferenceEngine(tiny_zoo.store).act, requests))
    assert concurrent == sequential
