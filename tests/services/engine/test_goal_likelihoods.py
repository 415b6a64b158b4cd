"""InferenceEngine.goal_log_likelihoods against a naive evaluation (each task network loaded on
its own through `policy.qnet`, log softmax(Q/α) in float64), one stacked pass for all G networks,
the errors naming their field, recover_partner_actions, and a wiring smoke test of the belief.

The store holds a random-weight task network for every particle goal (G = 35, MLP 8-16-5, the
hidden layer scaled up so the policies depend on the state). Training α: 0.05, except goal 1 (none:
the engine's default 0.02) and goal 2 (0.2); the likelihood's default temperature is
`LIKELIHOOD_TEMPERING` times these. Goal 0 also has a version 2 under `latest` only.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
import safetensors.numpy
import torch

import services.engine.goal_inference as goal_inference
from envs.particle import GOAL_IDS
from envs.particle.world import observations, random_states, step_state
from model_store.entities import Lineage
from model_store.naming import task_model_name
from model_store.sql import SqlModelStore
from model_store.testing import qnet_spec, qnet_tensors
from policy.belief import (
    BeliefConfig,
    boltzmann_log_likelihoods,
    initial_log_belief,
    prior_log_probs,
    update_log_belief,
)
from policy.qnet import QNetSpec, qnet_from_safetensors
from services.engine import DEFAULT_TEMPERATURE, InferenceEngine, InvalidRequest, ModelNotFound
from services.engine.environments import env_runtime

SPEC = qnet_spec(obs_dim=8, n_actions=5, hidden=(16,))
G = len(GOAL_IDS)
ALPHAS: dict[int, float | None] = {1: None, 2: 0.2}  # goal index -> training α (else 0.05)
PINNED_GOAL = GOAL_IDS[0]
HIDDEN_SCALE = 10.0
ATOL = 1e-4  # float32 forwards (rtol ~1e-6 in Q), amplified by 1/α <= 50


def _weights(seed: int) -> bytes:
    """Hidden layers scaled up (weights ~ N(0, 1)) so the policy depends on the state and differs
    between goals; near-constant random policies would be hard to tell apart."""
    tensors = qnet_tensors(SPEC, seed=seed)
    for k in range(len(SPEC["hidden"])):
        for kind in ("weight", "bias"):
            tensors[f"layers.{k}.{kind}"] = tensors[f"layers.{k}.{kind}"] * HIDDEN_SCALE
    return safetensors.numpy.save(tensors)


def _register(store: SqlModelStore, goal_index: int, seed: int, aliases: tuple[str, ...]) -> None:
    goal = GOAL_IDS[goal_index]
    alpha = ALPHAS.get(goal_index, 0.05)
    name = task_model_name("particle", goal)
    store.create_model(
        name, env="particle", kind="task", goals=[goal], obs_dim=8, n_actions=5, exist_ok=True
    )
    store.register_version(
        name,
        spec=SPEC,
        weights=_weights(seed),
        lineage=Lineage(config={} if alpha is None else {"alpha": alpha}, seed=seed),
        aliases=aliases,
    )


@pytest.fixture(scope="module")
def store(tmp_path_factory: pytest.TempPathFactory) -> Iterator[SqlModelStore]:
    path = tmp_path_factory.mktemp("goal_zoo") / "models.db"
    with SqlModelStore(f"sqlite:///{path}") as store:
        for g in range(G):
            _register(store, g, seed=g, aliases=("latest", "production"))
        _register(store, 0, seed=1000, aliases=("latest",))  # version 2 of goal 0
        yield store


@pytest.fixture
def engine(store: SqlModelStore) -> InferenceEngine:
    return InferenceEngine(store)


# --- the naive reference ----------------------------------------------------------------------


class Naive:
    """Each goal's task network loaded on its own, as a torch `QNetwork`."""

    def __init__(self, store: SqlModelStore, versions: dict[str, int] | None = None) -> None:
        self.nets: list[Any] = []
        self.alphas: list[float] = []
        for goal in GOAL_IDS:
            name = task_model_name("particle", goal)
            pinned = (versions or {}).get(name)
            mv = store.resolve(f"{name}/{pinned}" if pinned else f"{name}@production")
            spec = QNetSpec.from_json(mv.spec)
            self.nets.append(qnet_from_safetensors(spec, store.load_weights(mv.name, mv.version)))
            training = mv.lineage.config.get("alpha", DEFAULT_TEMPERATURE)
            self.alphas.append(goal_inference.LIKELIHOOD_TEMPERING * training)

    def q(self, g: int, view: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            return self.nets[g](torch.as_tensor(view, dtype=torch.float32)).double().numpy()

    def log_policy(self, g: int, view: np.ndarray, alpha: float | None = None) -> np.ndarray:
        z = self.q(g, view) / (alpha or self.alphas[g])
        z -= z.max()
        return z - np.log(np.exp(z).sum())

    def log_likelihoods(
        self, obs_D: np.ndarray, partners: list[int], actions: list[int], alpha: float | None = None
    ) -> np.ndarray:
        blocks = obs_D.reshape(-1, 4)
        out = np.empty((len(partners), G))
        for p, (index, action) in enumerate(zip(partners, actions, strict=True)):
            view = np.r_[blocks[index], blocks[0]]  # the pair as the partner sees it
            for g in range(G):
                out[p, g] = self.log_policy(g, view, alpha)[action]
        return out


def _obs(rng: np.random.Generator, n_agents: int) -> np.ndarray:
    state = random_states(rng, (), n_agents)
    state[:, 2:] = rng.uniform(-0.5, 0.5, (n_agents, 2))
    return observations(state)[0].astype(np.float32)


# --- numbers ----------------------------------------------------------------------------------


@pytest.mark.parametrize("n_agents", [2, 3, 4, 5])
def test_likelihoods_equal_the_naive_evaluation(
    engine: InferenceEngine, store: SqlModelStore, n_agents: int
) -> None:
    naive = Naive(store)
    rng = np.random.default_rng(n_agents)
    for _ in range(3):
        obs = _obs(rng, n_agents)
        partners = [int(i) for i in rng.permutation(np.arange(1, n_agents))]
        actions = [int(a) for a in rng.integers(0, 5, len(partners))]
        got = engine.goal_log_likelihoods("particle", obs, partners, actions)
        assert got.shape == (len(partners), G)
        np.testing.assert_allclose(got, naive.log_likelihoods(obs, partners, actions), atol=ATOL)
        # each row is a log-probability of a policy: the 5 actions' likelihoods sum to 1
        per_action = [
            engine.goal_log_likelihoods("particle", obs, partners[:1], [a]) for a in range(5)
        ]
        np.testing.assert_allclose(np.exp(per_action).sum(axis=0), 1.0, atol=1e-5)


def test_training_alpha_per_goal_and_the_temperature_override(
    engine: InferenceEngine, store: SqlModelStore
) -> None:
    naive = Naive(store)
    tempering = goal_inference.LIKELIHOOD_TEMPERING
    assert tempering > 1  # tempered: partners are not the ego's copy of their networks
    assert naive.alphas[0] == tempering * 0.05
    assert naive.alphas[1] == tempering * DEFAULT_TEMPERATURE
    assert naive.alphas[2] == tempering * 0.2
    obs = _obs(np.random.default_rng(1), 2)
    got = engine.goal_log_likelihoods("particle", obs, [1], [2])
    np.testing.assert_allclose(got, naive.log_likelihoods(obs, [1], [2]), atol=ATOL)
    hot = engine.goal_log_likelihoods("particle", obs, [1], [2], temperature=0.7)
    np.testing.assert_allclose(hot, naive.log_likelihoods(obs, [1], [2], alpha=0.7), atol=ATOL)
    assert not np.allclose(hot, got, atol=0.01)


@pytest.mark.parametrize("noise", [0.05, 0.3])
def test_the_noise_mixes_each_policy_with_uniform_actions(
    engine: InferenceEngine, store: SqlModelStore, noise: float
) -> None:
    # log((1 - η) π_g(a) + η / A) with π_g the naive network's policy, in probabilities
    naive = Naive(store)
    rng = np.random.default_rng(5)
    obs = _obs(rng, 3)
    got = engine.goal_log_likelihoods("particle", obs, [2, 1], [4, 0], noise=noise)
    want = np.log((1 - noise) * np.exp(naive.log_likelihoods(obs, [2, 1], [4, 0])) + noise / 5)
    np.testing.assert_allclose(got, want, atol=ATOL)
    # still a distribution over the actions, and the same numbers from a table made ahead
    per_action = [
        engine.goal_log_likelihoods("particle", obs, [1], [a], noise=noise) for a in range(5)
    ]
    np.testing.assert_allclose(np.exp(per_action).sum(axis=0), 1.0, atol=1e-5)
    runtime = env_runtime("particle")
    versions: dict[str, int] = {}
    table = goal_inference.likelihood_table(
        engine.cache,
        runtime,
        obs,
        3,
        (2, 1),
        alias="production",
        versions=versions,
        temperature=None,
        noise=noise,
    )
    group = goal_inference.task_group(engine.cache, runtime, "production", versions)
    picked = table.pick(group, [2, 1], np.array([4, 0]))
    assert picked is not None
    np.testing.assert_array_equal(picked, got)  # bit for bit


def test_pinned_versions_and_aliases_are_honoured(
    engine: InferenceEngine, store: SqlModelStore
) -> None:
    name = task_model_name("particle", PINNED_GOAL)
    obs = _obs(np.random.default_rng(2), 2)
    production = engine.goal_log_likelihoods("particle", obs, [1], [4])
    pinned = engine.goal_log_likelihoods("particle", obs, [1], [4], versions={name: 2})
    latest = engine.goal_log_likelihoods("particle", obs, [1], [4], alias="latest")
    np.testing.assert_allclose(
        pinned, Naive(store, {name: 2}).log_likelihoods(obs, [1], [4]), atol=ATOL
    )
    np.testing.assert_allclose(latest, pinned, atol=1e-12)
    assert abs(pinned[0, 0] - production[0, 0]) > 1e-3  # goal 0 changed, the others did not
    np.testing.assert_allclose(pinned[0, 1:], production[0, 1:], atol=1e-12)


def test_a_reload_reaches_the_fixed_set_of_task_networks(
    engine: InferenceEngine, store: SqlModelStore
) -> None:
    """The 35 names resolve as one fixed set after the first call (one look-up, the per-name
    counters); moving an alias and refreshing voids it, so the new version is used at once."""
    name = task_model_name("particle", PINNED_GOAL)
    obs = _obs(np.random.default_rng(4), 2)
    before = engine.goal_log_likelihoods("particle", obs, [1], [3])
    hits = engine.stats.resolve_hits
    np.testing.assert_array_equal(engine.goal_log_likelihoods("particle", obs, [1], [3]), before)
    assert engine.stats.resolve_hits == hits + G
    store.set_alias(name, "production", 2)
    try:
        assert engine.refresh() is True
        moved = engine.goal_log_likelihoods("particle", obs, [1], [3])
    finally:
        store.set_alias(name, "production", 1)
    pinned = engine.goal_log_likelihoods("particle", obs, [1], [3], versions={name: 2})
    np.testing.assert_array_equal(moved, pinned)
    assert moved[0, 0] != before[0, 0]
    np.testing.assert_array_equal(moved[0, 1:], before[0, 1:])


def test_no_partners_gives_an_empty_table(engine: InferenceEngine) -> None:
    got = engine.goal_log_likelihoods("particle", np.zeros(8), [], [])
    assert got.shape == (0, G)


def test_the_softmax_is_boltzmann_log_likelihoods() -> None:
    """`_log_likelihoods` (the forward's (G, P, A) layout, compiled or errstate only for a tiny
    α) gives the numbers of `policy.belief.boltzmann_log_likelihoods` within 1e-12 (the same
    infinities), without a warning: huge Q-values, α per goal or one for all, and α small
    enough that Q / α overflows to -inf."""
    rng = np.random.default_rng(17)
    for trial in range(600):
        n_goals, n_partners, n_actions = (int(rng.integers(1, n)) for n in (40, 6, 7))
        scale = float(rng.choice([1.0, 100.0, 1e30, 3e38]))
        q_GPA = np.clip(
            rng.standard_normal((n_goals, n_partners, n_actions)) * scale, -3.4e38, 3.4e38
        ).astype(np.float32)
        actions_P = rng.integers(0, n_actions, n_partners)
        if trial % 2:
            alpha: Any = float(rng.choice([0.02, 1e-6, 1e-300, 5.0]))
            shaped, tiny = alpha, alpha < goal_inference.TINY_ALPHA
        else:
            alpha = rng.choice([0.02, 0.05, 1e-260, 1.0], size=n_goals)
            shaped, tiny = alpha[:, None, None], bool(alpha.min() < goal_inference.TINY_ALPHA)
        expected = boltzmann_log_likelihoods(q_GPA.transpose(1, 0, 2), actions_P, alpha)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            got = goal_inference._log_likelihoods(q_GPA, actions_P, shaped, tiny)
        assert got.shape == expected.shape
        finite = np.isfinite(expected)
        np.testing.assert_array_equal(np.isfinite(got), finite)
        np.testing.assert_array_equal(got[~finite], expected[~finite])
        np.testing.assert_allclose(got[finite], expected[finite], rtol=1e-12, atol=1e-12)


# --- one stacked pass -------------------------------------------------------------------------


def test_one_stacked_group_and_one_forward_of_all_networks(
    engine: InferenceEngine, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls: list[tuple[int, int]] = []  # (networks, rows) of each stacked forward
    forward = goal_inference.row_forward

    def spy(x_1PF: np.ndarray, layers: Any, start: int, members: int, act: str) -> np.ndarray:
        calls.append((members, x_1PF.shape[1]))
        return forward(x_1PF, layers, start, members, act)

    monkeypatch.setattr(goal_inference, "row_forward", spy)
    rng = np.random.default_rng(3)
    engine.goal_log_likelihoods("particle", _obs(rng, 2), [1], [0])
    assert calls == [(G, 1)]  # every goal's network in one pass
    assert (engine.stats.stack_misses, engine.stats.loads) == (1, G)
    calls.clear()
    engine.goal_log_likelihoods("particle", _obs(rng, 5), [4, 1, 3, 2], [1, 2, 3, 4])
    assert calls == [(G, 4)]
    calls.clear()
    engine.goal_log_likelihoods("particle", _obs(rng, 4), [1, 3], [1, 2])
    assert calls == [(G, 2)]  # any number of rows: one pass (the weights stream once)
    assert (engine.stats.stack_misses, engine.stats.stack_hits, engine.stats.loads) == (1, 2, G)


# --- errors -----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"observation": np.zeros(7)}, "observation"),
        ({"observation": np.zeros((1, 8))}, "observation"),
        ({"observation": [0.0] * 7 + [np.nan]}, "observation"),
        ({"observation": ["a"] * 8}, "observation"),
        ({"observation": [1e39] * 8}, "observation"),
        ({"partners": [2]}, "partners[0].index"),
        ({"partners": [0]}, "partners[0].index"),
        ({"partners": [1.0]}, "partners[0].index"),
        ({"partners": [True]}, "partners[0].index"),
        ({"observation": np.zeros(12), "partners": [1, 1], "actions": [0, 0]}, "partners[1].index"),
        ({"actions": [5]}, "observed[0].action"),
        ({"actions": [-1]}, "observed[0].action"),
        ({"actions": [1.0]}, "observed[0].action"),
        ({"actions": [None]}, "observed[0].action"),
        ({"actions": [0, 1]}, "observed"),
        ({"env": "nowhere"}, "env"),
        ({"temperature": 0.0}, "temperature"),
        ({"temperature": float("nan")}, "temperature"),
        ({"noise": 1.0}, "noise"),
        ({"noise": -0.1}, "noise"),
        ({"noise": float("nan")}, "noise"),
        ({"noise": "0.1"}, "noise"),
        ({"alias": "Not An Alias!"}, "alias"),
        ({"versions": {task_model_name("particle", "a2"): 0}}, "versions[particle/task/a2]"),
    ],
)
def test_bad_input_names_the_field(engine: InferenceEngine, kwargs: dict, field: str) -> None:
    args: dict[str, Any] = {
        "env": "particle",
        "observation": np.zeros(8),
        "partners": [1],
        "actions": [0],
    }
    args.update(kwargs)
    extra = {k: args.pop(k) for k in ("temperature", "noise", "alias", "versions") if k in args}
    with pytest.raises(InvalidRequest) as err:
        engine.goal_log_likelihoods(
            args["env"], args["observation"], args["partners"], args["actions"], **extra
        )
    assert err.value.field == field, err.value


def test_a_missing_task_network_is_model_not_found(engine: InferenceEngine) -> None:
    with pytest.raises(ModelNotFound) as err:
        engine.goal_log_likelihoods("particle", np.zeros(8), [1], [0], alias="staging")
    assert err.value.name == task_model_name("particle", GOAL_IDS[0])
    assert err.value.field == "partners"
    assert "every goal" in err.value.message


def test_overflowing_observations_are_refused(engine: InferenceEngine) -> None:
    with pytest.raises(InvalidRequest) as err:
        engine.goal_log_likelihoods("particle", np.full(8, 3e38, dtype=np.float32), [1], [0])
    assert err.value.field == "observation"


# --- recovering actions -----------------------------------------------------------------------


def test_recover_partner_actions_in_the_particle_world(engine: InferenceEngine) -> None:
    rng = np.random.default_rng(4)
    state = random_states(rng, (), 4)
    state[:, :2] = 0.2 + 0.6 * state[:, :2]  # away from the walls: every action distinct
    actions = np.array([0, 4, 1, 3])
    before, after = observations(state)[0], observations(step_state(state, actions))[0]
    assert engine.recover_partner_actions("particle", before, after, [3, 1]) == [3, 4]
    assert engine.recover_partner_actions("particle", before, after, []) == []


def test_recover_partner_actions_errors(engine: InferenceEngine) -> None:
    obs8, obs12 = np.zeros(8), np.zeros(12)
    cases = [
        (("particle", obs8, obs12, [1]), "observation"),
        (("particle", np.zeros(5), obs8, [1]), "previous"),
        (("particle", obs8, obs8, [2]), "partners[0].index"),
        (("cooking", np.zeros(188), np.zeros(188), [1]), "observed"),
    ]
    for args, field in cases:
        with pytest.raises(InvalidRequest) as err:
            engine.recover_partner_actions(*args)
        assert err.value.field == field, (args, err.value)
    with pytest.raises(InvalidRequest, match="send each partner's action"):
        engine.recover_partner_actions("cooking", np.zeros(188), np.zeros(188), [1])


# --- wiring smoke: the belief finds the goal the partner acts by ------------------------------


def test_the_belief_finds_a_partner_following_its_task_policy(
    engine: InferenceEngine, store: SqlModelStore
) -> None:
    """Random-weight networks, so this checks the wiring (views, goal order, α, update), not
    learned behaviour: the partner samples from softmax(Q_g / α_g) of goal g's network."""
    naive = Naive(store)
    config = BeliefConfig()
    prior = prior_log_probs(GOAL_IDS)
    hits, seeds = 0, 12
    for seed in range(seeds):
        rng = np.random.default_rng(100 + seed)
        true_goal = int(rng.integers(G))
        state = random_states(rng, (), 2)
        belief = initial_log_belief(prior, config)[None]
        for _ in range(40):
            obs = observations(state)  # (2, 8): the ego's and the partner's own observation
            policy = np.exp(naive.log_policy(true_goal, obs[1]))
            action = int(rng.choice(5, p=policy / policy.sum()))
            log_lik = engine.goal_log_likelihoods("particle", obs[0], [1], [action])
            belief = update_log_belief(belief, log_lik, prior, config)
            state = step_state(state, np.array([int(rng.integers(5)), action]))
        hits += int(np.argmax(belief[0])) == true_goal
    # ~80% over 30 seeds with this zoo; "most" is all the wiring check asks
    assert hits > seeds // 2, f"top goal right in {hits} of {seeds} seeds"
