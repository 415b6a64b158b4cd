"""The session core (services.sessions) over a particle zoo of random networks: the belief follows
the partner's task policy, a step is the engine's act with the belief's goal distribution,
expiry, the limit, conflicts, concurrency, and bad steps that change nothing."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from session_zoo import partner_action, random_observation, session_zoo_template

from envs.particle.goals import GOAL_IDS
from envs.particle.world import observations, step_state
from model_store.sql import SqlModelStore
from policy.belief import (
    BeliefConfig,
    blend_goal_probs,
    initial_log_belief,
    prior_log_probs,
    update_log_belief,
)
from services.engine import ActRequest, InferenceEngine, InvalidRequest, PartnerSpec
from services.sessions import (
    Observed,
    Session,
    SessionLimitReached,
    SessionNotFound,
    SessionPartner,
    SessionSettings,
    SessionStore,
    StepConflict,
)


@pytest.fixture(scope="module")
def engine(tmp_path_factory: pytest.TempPathFactory) -> Iterator[InferenceEngine]:
    with SqlModelStore(f"sqlite:///{session_zoo_template(tmp_path_factory)}") as store:
        yield InferenceEngine(store)


class Clock:
    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


def inferred(seed: int | None = 5, **kwargs: Any) -> SessionSettings:
    return SessionSettings("particle", "a2", (SessionPartner(1, infer=True),), seed=seed, **kwargs)


def run_partner(
    store: SessionStore,
    session_id: str,
    engine: InferenceEngine,
    goal: str,
    steps: int,
    seed: int = 0,
) -> list[Any]:
    """Steps whose partner acts by `goal`'s task policy; the answers."""
    rng, previous, answers = np.random.default_rng(seed), None, []
    for _ in range(steps):
        obs = random_observation(rng)
        observed: list[Observed] = []
        if previous is not None:
            observed = [Observed(1, partner_action(engine, previous, 1, goal))]
        answers.append(store.step(session_id, obs, observed))
        previous = obs
    return answers


@pytest.mark.parametrize("goal", ["c1", "e4", "b"])
def test_belief_moves_to_the_goal_whose_policy_the_partner_follows(
    engine: InferenceEngine, goal: str
) -> None:
    store = SessionStore(engine)
    info = store.create(inferred())
    assert info.beliefs[0].entropy == pytest.approx(np.log(len(GOAL_IDS)))  # uniform prior
    answers = run_partner(store, info.session_id, engine, goal, steps=15)
    probs = [dict(a.beliefs[0].top).get(goal, 0.0) for a in answers]
    assert answers[-1].beliefs[0].top[0][0] == goal
    assert info.beliefs[0].top[0][1] == pytest.approx(1 / len(GOAL_IDS))
    assert probs[-1] > 0.5
    assert answers[-1].beliefs[0].entropy < answers[0].beliefs[0].entropy - 1.0
    assert [a.beliefs[0].updates for a in answers] == list(range(15))
    assert answers[0].beliefs[0].observed_action is None


@pytest.mark.parametrize("noise", [0.0, 0.1])
def test_a_step_acts_with_the_beliefs_blend_and_seed_plus_t(
    engine: InferenceEngine, noise: float
) -> None:
    config = BeliefConfig(forgetting=0.9, floor=1e-3, noise=noise)
    settings = SessionSettings(
        "particle",
        "a2",
        (SessionPartner(1, goal="c1", infer=True), SessionPartner(2, goal="d4")),
        seed=11,
        belief=config,
        blend_mass=0.9,
        blend_max_goals=3,
    )
    session = Session(engine, settings)
    log_prior = prior_log_probs(GOAL_IDS, announced="c1")
    log_b = initial_log_belief(log_prior, config)
    rng, previous = np.random.default_rng(1), np.zeros(12)
    for t in range(3):
        obs = random_observation(rng, n_agents=3)
        observed = [Observed(1, 2)] if t else []
        if t:  # the update by hand: a_{t-1} = 2 judged on the previous observation, the
            # policy mixed with uniform actions: (1 - η) π_g(2) + η / 5
            plain = engine.goal_log_likelihoods("particle", previous, [1], [2])
            lik = engine.goal_log_likelihoods("particle", previous, [1], [2], noise=noise)
            np.testing.assert_allclose(
                np.exp(lik), (1 - noise) * np.exp(plain) + noise / 5, rtol=1e-12
            )
            log_b = update_log_belief(log_b[None], lik, log_prior[None], config)[0]
        goal_probs = blend_goal_probs(log_b, GOAL_IDS, 0.9, 3)
        expected = engine.act(
            ActRequest(
                "particle",
                "a2",
                obs[None],
                (PartnerSpec(1, goal_probs=goal_probs), PartnerSpec(2, goal="d4")),
                seed=11 + t,
            )
        )[0]
        answer = session.step(obs, observed)
        assert answer.step == t
        assert answer.result == expected
        assert dict(answer.beliefs[0].top) == pytest.approx(
            dict(sorted(zip(GOAL_IDS, np.exp(log_b), strict=True), key=lambda x: -x[1])[:3])
        )
        previous = obs


def test_an_announced_goal_is_the_prior(engine: InferenceEngine) -> None:
    session = Session(
        engine, SessionSettings("particle", "a2", (SessionPartner(1, "e4", infer=True),))
    )
    _, (belief,) = session.snapshot()
    floor = 1e-3  # the default: b = (1 - Gε) prior + ε
    assert belief.top[0] == ("e4", pytest.approx(0.9 * (1 - len(GOAL_IDS) * floor) + floor))


def test_recovered_actions_are_those_the_partner_took(engine: InferenceEngine) -> None:
    session = Session(engine, inferred())
    state = np.array([[[0.2, 0.3, 0.0, 0.0], [0.7, 0.6, 0.05, 0.0]]])
    session.step(observations(state)[0, 0])
    for action in (3, 1, 0, 4):
        state = step_state(state, np.array([[0, action]]))
        answer = session.step(observations(state)[0, 0], [Observed(1)])
        assert answer.beliefs[0].observed_action == action


def test_idle_sessions_expire_and_say_so(engine: InferenceEngine) -> None:
    clock = Clock()
    store = SessionStore(engine, ttl_s=30.0, clock=clock)
    info = store.create(inferred())
    clock.now += 29.0
    store.step(info.session_id, np.zeros(8))  # a step restarts the idle time
    clock.now += 29.0
    assert store.get(info.session_id).expires_in_s == pytest.approx(1.0)
    clock.now += 1.0
    for call in (
        lambda: store.get(info.session_id),
        lambda: store.step(info.session_id, np.zeros(8)),
    ):
        with pytest.raises(SessionNotFound) as err:
            call()
        assert err.value.field == "session_id"
        assert info.session_id in err.value.message
        assert "expired after 30 s idle" in err.value.message
    assert len(store) == 0


def test_deleted_and_unknown_sessions_are_not_found_with_the_reason(
    engine: InferenceEngine,
) -> None:
    store = SessionStore(engine)
    info = store.create(inferred())
    store.delete(info.session_id)
    with pytest.raises(SessionNotFound, match="was deleted"):
        store.step(info.session_id, np.zeros(8))
    with pytest.raises(SessionNotFound, match="another server process"):
        store.get("no-such-session")
    with pytest.raises(SessionNotFound):
        store.delete(info.session_id)


def test_the_limit_refuses_new_sessions_until_one_expires(engine: InferenceEngine) -> None:
    clock = Clock()
    store = SessionStore(engine, max_sessions=2, ttl_s=10.0, clock=clock)
    first = store.create(inferred())
    clock.now += 5.0
    store.create(inferred())
    with pytest.raises(SessionLimitReached, match="maximum of 2"):
        store.create(inferred())
    clock.now += 5.0  # the first one expires; creating purges it
    store.create(inferred())
    assert len(store) == 2
    with pytest.raises(SessionNotFound, match="expired"):
        store.get(first.session_id)


def test_expected_step_conflicts_change_nothing(engine: InferenceEngine) -> None:
    store = SessionStore(engine)
    info = store.create(inferred())
    store.step(info.session_id, np.zeros(8), expected_step=0)
    with pytest.raises(StepConflict) as err:
        store.step(info.session_id, np.ones(8), [Observed(1, 2)], expected_step=0)  # a retry
    assert (err.value.field, err.value.expected, err.value.actual) == ("expected_step", 0, 1)
    after = store.get(info.session_id)
    assert after.step == 1 and after.beliefs[0].updates == 0
    assert store.step(info.session_id, np.ones(8), [Observed(1, 2)], expected_step=1).step == 1


def test_concurrent_steps_on_one_session_are_serialised(engine: InferenceEngine) -> None:
    store = SessionStore(engine)
    info = store.create(inferred(seed=None))
    store.step(info.session_id, np.zeros(8))
    per_thread, steps, errors = 10, [], []
    lock = threading.Lock()

    def work(k: int) -> None:
        rng = np.random.default_rng(k)
        try:
            for _ in range(per_thread):
                answer = store.step(info.session_id, random_observation(rng), [Observed(1, k % 5)])
                with lock:
                    steps.append(answer.step)
        except Exception as exc:  # reported below
            errors.append(exc)

    threads = [threading.Thread(target=work, args=(k,)) for k in range(8)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert not errors
    assert sorted(steps) == list(range(1, 8 * per_thread + 1))
    final = store.get(info.session_id)
    assert final.step == 8 * per_thread + 1
    assert final.beliefs[0].updates == 8 * per_thread


BAD_STEPS = [
    ("observation", dict(observation=np.zeros(7))),
    ("observation", dict(observation=[0.0] * 7 + [float("nan")])),
    ("observed[0].index", dict(observed=[Observed(2, 1)])),
    ("observed[1].index", dict(observed=[Observed(1, 1), Observed(1, 2)])),
    ("observed[0].action", dict(observed=[Observed(1, 5)])),
    ("observed[0].action", dict(observed=[Observed(1, -1)])),
    ("expected_step", dict(expected_step="1")),
]


@pytest.mark.parametrize(("field", "change"), BAD_STEPS)
def test_a_bad_step_names_the_field_and_changes_nothing(
    engine: InferenceEngine, field: str, change: dict[str, Any]
) -> None:
    store = SessionStore(engine)
    info = store.create(inferred())
    store.step(info.session_id, np.full(8, 0.1))
    before = store.get(info.session_id)
    step: dict[str, Any] = {"observation": np.full(8, 0.2), "observed": [Observed(1, 3)]}
    step.update(change)
    with pytest.raises(InvalidRequest) as err:
        store.step(
            info.session_id, step["observation"], step["observed"], step.get("expected_step")
        )
    assert err.value.field == field
    after = store.get(info.session_id)
    assert (after.step, after.beliefs) == (before.step, before.beliefs)
    # ... and the next good step is the one an untouched session makes
    twin = store.create(inferred())
    store.step(twin.session_id, np.full(8, 0.1))
    good = (np.full(8, 0.2), [Observed(1, 3)])
    a, b = store.step(info.session_id, *good), store.step(twin.session_id, *good)
    assert (a.step, a.result, a.beliefs) == (b.step, b.result, b.beliefs)


def test_observed_at_step_0_is_refused(engine: InferenceEngine) -> None:
    store = SessionStore(engine)
    info = store.create(inferred())
    with pytest.raises(InvalidRequest, match="no previous observation") as err:
        store.step(info.session_id, np.zeros(8), [Observed(1, 0)])
    assert err.value.field == "observed"
    assert store.get(info.session_id).step == 0


def test_an_observed_partner_must_be_inferred(engine: InferenceEngine) -> None:
    settings = SessionSettings("particle", "a2", (SessionPartner(1, "b3"),))
    session = Session(engine, settings)
    session.step(np.zeros(8))
    with pytest.raises(InvalidRequest, match="not an inferred partner") as err:
        session.step(np.zeros(8), [Observed(1, 0)])
    assert err.value.field == "observed[0].index"


BAD_SETTINGS = [
    ("env", dict(env="chess")),
    ("ego_goal", dict(ego_goal="zz")),
    ("partners[0].index", dict(partners=(SessionPartner(5, infer=True),))),
    ("partners[1].index", dict(partners=(SessionPartner(1), SessionPartner(1)))),
    ("partners[0].goal", dict(partners=(SessionPartner(1, "zz", infer=True),))),
    ("partners[0].goal_probs", dict(partners=(SessionPartner(1, goal_probs={"a0": 0.5}),))),
    ("partners[0].infer", dict(partners=(SessionPartner(1, infer=True),), method="jl")),
    ("method", dict(method="best")),
    ("temperature", dict(temperature=-1.0)),
    ("regret_bound", dict(regret_bound=-0.5)),
    ("regret_bound", dict(method="sl", regret_bound=0.5)),
    ("seed", dict(seed=-3)),
    ("belief.forgetting", dict(belief=BeliefConfig(forgetting=1.5))),
    ("belief.floor", dict(belief=BeliefConfig(floor=0.5))),
    ("belief.temperature", dict(belief=BeliefConfig(temperature=0.0))),
    ("belief.noise", dict(belief=BeliefConfig(noise=1.0))),
    ("belief.noise", dict(belief=BeliefConfig(noise=-0.5))),
    ("belief.blend_mass", dict(blend_mass=0.0)),
    ("belief.blend_max_goals", dict(blend_max_goals=0)),
]


@pytest.mark.parametrize(("field", "change"), BAD_SETTINGS)
def test_bad_settings_are_refused_at_creation_naming_the_field(
    engine: InferenceEngine, field: str, change: dict[str, Any]
) -> None:
    fields: dict[str, Any] = {
        "env": "particle",
        "ego_goal": "a2",
        "partners": (SessionPartner(1, infer=True),),
    }
    fields.update(change)
    store = SessionStore(engine)
    with pytest.raises(InvalidRequest) as err:
        store.create(SessionSettings(**fields))
    assert err.value.field == field
    assert len(store) == 0


def test_replaced_settings_keep_the_belief_of_a_partner_still_inferred(
    engine: InferenceEngine,
) -> None:
    session = Session(engine, inferred(seed=1))
    session.step(np.zeros(8))
    session.step(np.full(8, 0.3), [Observed(1, 4)])
    _, before = session.snapshot()
    session.replace_settings(SessionSettings("particle", "b3", (SessionPartner(1, infer=True),)))
    step, after = session.snapshot()
    assert step == 2 and after[0].top == before[0].top and after[0].updates == 1
    session.replace_settings(SessionSettings("particle", "b3", (SessionPartner(1, "c1"),)))
    assert session.snapshot()[1] == ()
    assert session.step(np.zeros(8)).step == 2


def test_a_step_failing_after_the_update_changes_nothing(engine: InferenceEngine) -> None:
    """The belief update succeeds on the stored 3-agent observation, then the act fails (this
    observation holds 2 agents, partner 2 is gone): nothing of the update may stay."""
    partners = (SessionPartner(1, infer=True), SessionPartner(2, "c1"))
    session = Session(engine, SessionSettings("particle", "a2", partners, seed=2))
    session.step(np.full(12, 0.1))
    before = session.snapshot()
    with pytest.raises(InvalidRequest) as err:
        session.step(np.full(8, 0.2), [Observed(1, 3)])
    assert err.value.field == "partners[1].index"
    assert session.snapshot() == before
    assert session.step(np.full(12, 0.2), [Observed(1, 3)]).beliefs[0].updates == 1
