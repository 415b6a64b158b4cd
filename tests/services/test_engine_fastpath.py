"""The engine's single-row fast path against its general path (same engine, `act_row` switched
off): numbers, diagnostics, models, sampled actions, errors and cache counters; the layouts it
declines; the input gathers it derives from the domain; thread safety."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import services.engine.engine as engine_module
import services.engine.fastpath as fastpath
from envs.registry import get_domain
from policy.qnet import QNetSpec
from services.engine import ActRequest, ActResult, InferenceEngine, InvalidRequest, PartnerSpec
from services.engine.gathers import find_gather

GOALS = ("b3", "c1", "d4", "e0", "c")
ATOL = 1e-6  # float32 rounding of the forward, amplified by 1/α = 20 (the zoo's α, 0.05)


def _general(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(engine_module, "act_row", lambda *args: None)


def _both(tiny_zoo, request: ActRequest) -> tuple[list[ActResult], list[ActResult]]:
    """(fast, general) results of one request, from two fresh engines."""
    fast = InferenceEngine(tiny_zoo.store).act(request)
    with pytest.MonkeyPatch.context() as patch:
        _general(patch)
        general = InferenceEngine(tiny_zoo.store).act(request)
    return fast, general


def _assert_close(fast: ActResult, general: ActResult, atol: float = ATOL) -> None:
    np.testing.assert_allclose(fast.probs, general.probs, rtol=1e-5, atol=atol)
    assert (fast.action, fast.greedy_action, fast.method) == (
        general.action,
        general.greedy_action,
        general.method,
    )
    assert fast.task_entropy == pytest.approx(general.task_entropy, abs=atol)
    assert fast.task_weight == pytest.approx(general.task_weight, abs=atol)
    np.testing.assert_allclose(fast.partner_weights, general.partner_weights, atol=atol)
    assert fast.models == general.models
    assert all(type(p) is float for p in fast.probs)


@st.composite
def requests(draw) -> ActRequest:
    n_agents = draw(st.integers(1, 5))
    n_partners = draw(st.integers(0, n_agents - 1))
    indices = draw(st.permutations(range(1, n_agents)))[:n_partners]
    goals = draw(st.permutations(GOALS))  # distinct goals: every layout fits the fast path
    partners = []
    for index, goal in zip(indices, goals, strict=False):
        if draw(st.booleans()):
            partners.append(PartnerSpec(index, goal=goal))
        else:  # a distribution; its other goal gets probability 0 half of the time
            p = draw(st.sampled_from([0.0, 0.3, 1.0]))
            partners.append(PartnerSpec(index, goal_probs={goal: 1.0 - p, "a2": p}))
    if sum(1 for p in partners if p.goal_probs and p.goal_probs["a2"] > 0) > 1:
        partners = partners[:1]  # "a2" may serve one slot only
    obs = np.random.default_rng(draw(st.integers(0, 99))).normal(size=(1, 4 * n_agents))
    return ActRequest(
        "particle",
        draw(st.sampled_from(["a2", "b3", "c1"])),
        obs.astype(draw(st.sampled_from([np.float64, np.float32]))),
        tuple(partners),
        method=draw(st.sampled_from(["sl", "nail", "aail"])),
        temperature=draw(st.sampled_from([None, 0.01, 1.0])),
        seed=draw(st.sampled_from([None, 3, 12345])),
    )


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(request=requests())
def test_fast_path_equals_general_path(tiny_zoo, request: ActRequest) -> None:
    if request.seed is None:  # each path draws from its own unseeded generator
        request = ActRequest(**{**vars(request), "seed": 7})
    [fast], [general] = _both(tiny_zoo, request)
    # the paths differ by float32 rounding (the forward; the task views averaged in float64 or
    # float32), amplified by 1/α: a temperature of 0.01 amplifies 5x more than the zoo's 0.05
    _assert_close(fast, general, ATOL * max(1.0, 0.05 / (request.temperature or 0.05)))


def test_fast_path_is_taken_and_declines_shared_impact_networks(tiny_zoo, monkeypatch) -> None:
    calls: list[bool] = []
    act_row = fastpath.act_row

    def spy(*args: Any) -> Any:
        result = act_row(*args)
        calls.append(result is not None)
        return result

    monkeypatch.setattr(engine_module, "act_row", spy)
    engine = InferenceEngine(tiny_zoo.store)
    obs = np.random.default_rng(1).random((1, 12))
    distinct = (PartnerSpec(1, goal="b3"), PartnerSpec(2, goal="c1"))
    shared = (PartnerSpec(1, goal="b3"), PartnerSpec(2, goal_probs={"b3": 0.5, "c1": 0.5}))
    engine.act(ActRequest("particle", "a2", obs, distinct, seed=1))
    [declined] = engine.act(ActRequest("particle", "a2", obs, shared, seed=1))
    engine.act(ActRequest("particle", "a2", obs, distinct, method="jl"))
    engine.act(ActRequest("particle", "a2", np.repeat(obs, 2, axis=0), distinct))
    assert calls == [True, False]  # neither jl nor a batch of two asks
    monkeypatch.undo()
    [fast], [general] = _both(tiny_zoo, ActRequest("particle", "a2", obs, shared, seed=1))
    assert fast == general == declined  # the general path answered both


def test_a_distributions_mix_in_numpy_gives_the_bits_of_the_python_sum(
    tiny_zoo, monkeypatch
) -> None:
    """From `MIX_NUMPY_MIN` goals on, a distribution's impact Q-values are mixed in numpy; the
    sum runs in the same order, so the results are those of the Python loop, bit for bit."""
    goals = ("a2", *GOALS)
    rng = np.random.default_rng(4)
    obs = rng.normal(size=(1, 8))
    for _ in range(5):
        probs = dict(zip(goals, rng.dirichlet(np.ones(len(goals))).tolist(), strict=True))
        request = ActRequest("particle", "b3", obs, (PartnerSpec(1, goal_probs=probs),), seed=5)
        results = []
        for threshold in (2, 100):  # numpy, then the Python loop (fresh engines: new layouts)
            monkeypatch.setattr(fastpath, "MIX_NUMPY_MIN", threshold)
            results.append(InferenceEngine(tiny_zoo.store).act(request))
        assert results[0] == results[1]
        assert len(results[0][0].models) == 1 + len(goals)


def test_networks_of_different_architectures(tiny_zoo) -> None:
    """The task net and an impact net in different partitions: rows split across them."""
    wide = QNetSpec(obs_dim=8, n_actions=5, hidden=(32, 8))
    version = tiny_zoo.register("particle/impact/c", "impact", ("c",), wide, seed=7, aliases=())
    partners = (PartnerSpec(1, goal="c"), PartnerSpec(2, goal="b3"), PartnerSpec(4, goal="d4"))
    obs = np.random.default_rng(8).random((1, 20))
    pinned = {"particle/impact/c": version}
    request = ActRequest("particle", "a2", obs, partners, versions=pinned, seed=5)
    [fast], [general] = _both(tiny_zoo, request)
    _assert_close(fast, general)
    assert fast.models[1].version == version


def test_domain_views_when_no_gather(tiny_zoo, monkeypatch) -> None:
    monkeypatch.setattr(fastpath, "find_gather", lambda build, obs_dim: None)
    monkeypatch.setattr(fastpath, "_GATHERS", {})  # no gather proved by an earlier test
    request = ActRequest(
        "particle",
        "c1",
        np.random.default_rng(2).random((1, 12)),
        (PartnerSpec(2, goal="e0"),),
        seed=2,  # both engines draw the same action
    )
    [fast], [general] = _both(tiny_zoo, request)
    _assert_close(fast, general)


def test_same_errors_and_counters(tiny_zoo) -> None:
    huge = np.full((1, 8), 3e38)  # finite in float32, the Q-values are not
    engines = [InferenceEngine(tiny_zoo.store), InferenceEngine(tiny_zoo.store)]
    errors = []
    for k, engine in enumerate(engines):
        with pytest.MonkeyPatch.context() as patch:
            if k == 1:
                _general(patch)
            for goal in ("a2", "b3", "a2"):
                engine.act(ActRequest("particle", goal, huge / 1e38, (PartnerSpec(1, goal="c1"),)))
            with pytest.raises(InvalidRequest) as err:
                engine.act(ActRequest("particle", "a2", huge, (PartnerSpec(1, goal="c1"),)))
            errors.append((err.value.field, err.value.message))
    assert errors[0] == errors[1] == ("observations", "values so large that the Q-values overflow")
    assert vars(engines[0].stats.snapshot()) == vars(engines[1].stats.snapshot())


def test_layout_memo_is_bounded(tiny_zoo, monkeypatch) -> None:
    builds: list[int] = []
    layout = fastpath._layout

    def counting(*args: Any) -> Any:
        builds.append(1)
        return layout(*args)

    monkeypatch.setattr(fastpath, "_layout", counting)
    monkeypatch.setattr(fastpath, "MEMO_MAX", 2)
    engine = InferenceEngine(tiny_zoo.store)
    obs = np.random.default_rng(3).random((1, 20))
    rounds = [
        [
            engine.act(ActRequest("particle", "a2", obs, (PartnerSpec(i, goal="b3"),), seed=0))
            for i in (1, 2, 3, 4)  # four layouts of one stacked group
        ]
        for _ in range(2)
    ]
    assert rounds[0] == rounds[1]
    assert len(builds) == 8  # two kept at most: every layout was built again in round two
    monkeypatch.setattr(fastpath, "MEMO_MAX", 256)
    builds.clear()
    for _ in range(2):
        engine.act(ActRequest("particle", "a2", obs, (PartnerSpec(1, goal="d4"),), seed=0))
    assert len(builds) == 1


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


@pytest.mark.parametrize("env", ["particle", "cooking"])
def test_gathers_reproduce_the_domain_views(env: str) -> None:
    domain = get_domain(env)
    rng = np.random.default_rng(5)
    for n_agents in range(1, domain.max_agents + 1):
        partners = list(rng.permutation(np.arange(1, n_agents)))

        def build(obs_BD: np.ndarray, n: int = n_agents, ps: list = partners) -> np.ndarray:
            views = [domain.task_views(obs_BD, n)]
            views += [domain.impact_view(obs_BD, n, int(p))[:, None, :] for p in ps]
            return np.concatenate(views, axis=1)

        gather = find_gather(build, domain.obs_dim(n_agents))
        if env == "particle":  # pure selections (and the phantom agent for n = 1)
            assert gather is not None
        if gather is not None:
            obs = rng.normal(size=(1, domain.obs_dim(n_agents))).astype(np.float32)
            np.testing.assert_array_equal(gather(obs[0])[:, 0, :], build(obs)[0])


def test_gathers_refuse_views_that_compute() -> None:
    def relative(obs: np.ndarray) -> np.ndarray:  # other minus ego: not a selection
        return (obs[:, None, 4:] - obs[:, None, :4]).astype(np.float32)

    def clipped(obs: np.ndarray) -> np.ndarray:  # a selection on small values only
        return np.clip(obs, -1e6, 1e6)[:, None, :]

    def zero_to_phantom(obs: np.ndarray) -> np.ndarray:  # a selection except at 0
        return np.where(obs == 0, np.float32(0.5), obs)[:, None, :]

    def strict(obs: np.ndarray) -> np.ndarray:  # refuses some inputs
        if (obs < 0).any():
            raise ValueError("negative")
        return obs[:, None, :]

    def widened(obs: np.ndarray) -> np.ndarray:  # right values, wrong dtype
        return obs[:, None, :].astype(np.float64)

    for build in (relative, clipped, zero_to_phantom, strict, widened):
        assert find_gather(build, 8) is None, build.__name__
    assert find_gather(lambda obs: obs[:, None, ::-1], 8) is not None


def test_a_gather_is_proved_once_per_layout_shape(tiny_zoo, monkeypatch) -> None:
    """A top-k blend makes a new stacked group whenever its goal set changes; the gather of
    its inputs depends only on the env, the agents and the partner slots, so it is proved once
    (~0.5 ms), and every group's answers still equal the general path's."""
    proved: list[int] = []
    find = fastpath.find_gather

    def counting(build: Any, obs_dim: int) -> Any:
        proved.append(obs_dim)
        return find(build, obs_dim)

    monkeypatch.setattr(fastpath, "find_gather", counting)
    monkeypatch.setattr(fastpath, "_GATHERS", {})
    obs = np.random.default_rng(4).random((1, 8))
    for goals in (("b3", "c1"), ("d4", "e0"), ("c", "b3")):  # three groups, one shape
        request = ActRequest(
            "particle",
            "a2",
            obs,
            (PartnerSpec(1, goal_probs={goals[0]: 0.25, goals[1]: 0.75}),),
            seed=3,  # unseeded, the two engines would sample their actions independently
        )
        [fast], [general] = _both(tiny_zoo, request)
        _assert_close(fast, general)
    assert len(proved) == 1
