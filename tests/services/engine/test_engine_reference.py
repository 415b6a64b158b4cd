"""The engine's numbers against a naive reference: one torch QNetwork forward per network and
view, written out by hand, then `policy.blend` row by row; batches against single rows; sampling.
"""

from __future__ import annotations

from typing import cast

import numpy as np
import pytest
import torch

from envs.particle.goals import TARGET_BOXES_G4, goal_index
from envs.particle.world import in_target, step_state
from model_store.sql import SqlModelStore
from policy.blend import BlendMethod, blend
from policy.maths import boltzmann
from policy.qnet import QNetSpec, qnet_from_safetensors
from policy.regret_bound import DEFAULT_EPSILON_PER_ALPHA
from services.engine import ActRequest, InferenceEngine, PartnerSpec

PHANTOM = np.array([0.5, 0.5, 0.0, 0.0])
PARTNER_GOALS = ("b3", "c1", "d4", "e0")
ATOL = 2e-5


def _q(store: SqlModelStore, name: str, version: int | None, x: np.ndarray) -> np.ndarray:
    """Q of network `name` (production, or `version`) on one input vector, in torch."""
    mv = store.resolve(f"{name}/{version}" if version else f"{name}@production")
    net = qnet_from_safetensors(
        QNetSpec.from_json(mv.spec), store.load_weights(mv.name, mv.version)
    )
    with torch.no_grad():
        return net(torch.as_tensor(x, dtype=torch.float32)).double().numpy()


def reference(
    store: SqlModelStore,
    obs_D: np.ndarray,
    ego_goal: str,
    partners: list[tuple[int, dict[str, float]]],
    method: str,
    alpha: float,
    versions: dict[str, int] | None = None,
    regret_bound: float | None = None,
):
    """(probs, task entropy, task weight, partner weights) of one row, computed naively;
    aail_bounded's ε defaults to twice `alpha` (the engine's: twice the task model's α)."""
    blocks = obs_D.reshape(-1, 4)
    ego, others = blocks[0], list(blocks[1:]) or [PHANTOM]
    if method == "jl":
        combo = "+".join([ego_goal, *(next(iter(g)) for _, g in sorted(partners))])
        q = _q(store, f"particle/joint/{combo}", None, obs_D)
        return boltzmann(q, alpha), None, None, None
    task_name = f"particle/task/{ego_goal}"
    pinned = versions or {}
    q_task = np.mean(
        [_q(store, task_name, pinned.get(task_name), np.r_[ego, o]) for o in others], axis=0
    )
    q_impacts = []
    if method != "sl":
        for index, goals in partners:
            pair = np.r_[ego, blocks[index]]
            names = {g: f"particle/impact/{g}" for g in goals}
            q_impacts.append(
                sum(p * _q(store, names[g], pinned.get(names[g]), pair) for g, p in goals.items())
            )
    q_impact = np.array(q_impacts).reshape(1, len(q_impacts), 5)
    kept = None
    if method == "aail_bounded":
        if regret_bound is None:
            regret_bound = DEFAULT_EPSILON_PER_ALPHA * alpha
        # the progress guard: no blending before the ego is inside its target area
        x, y = obs_D[0], obs_D[1]
        x0, x1, y0, y1 = TARGET_BOXES_G4[goal_index(ego_goal)]
        if not (x0 <= x <= x1 and y0 <= y <= y1):
            regret_bound = 0.0
        if regret_bound:
            kept = np.array([_stays_inside(ego.astype(np.float32), a, ego_goal) for a in range(5)])
            if kept.any():  # R3: the target reached and kept, the ego's reward is the same on K
                q_task = np.full_like(q_task, q_task.mean())
    out = blend(cast(BlendMethod, method), q_task[None], q_impact, alpha, regret_bound=regret_bound)
    weights = out.partner_weights_BP[0] if method != "sl" else np.zeros(len(partners))
    probs = out.probs_BA[0]
    # R4: no action that loses the target area
    if kept is not None and kept.any() and not kept.all() and probs[kept].sum() > 0:
        probs = np.where(kept, probs, 0.0) / probs[kept].sum()
    return probs, out.task_entropy_B[0], out.task_weight_B[0], weights


def _stays_inside(ego_4: np.ndarray, action: int, goal: str, rests: int = 60) -> bool:
    """The ego inside its target area after `action` and after each of `rests` rests."""
    goal_1 = np.array([goal_index(goal)])
    state = step_state(np.asarray(ego_4, dtype=np.float64)[None], np.array([action]))
    inside = bool(in_target(state, goal_1)[0])
    for _ in range(rests):
        state = step_state(state, np.array([0]))
        inside &= bool(in_target(state, goal_1)[0])
    return inside


def _specs(partners: list[tuple[int, dict[str, float]]]) -> tuple[PartnerSpec, ...]:
    return tuple(
        PartnerSpec(i, goal=next(iter(g))) if len(g) == 1 else PartnerSpec(i, goal_probs=g)
        for i, g in partners
    )


def _check_row(result, ref) -> None:
    probs, entropy, w_task, w_partners = ref
    np.testing.assert_allclose(result.probs, probs, atol=ATOL)
    assert result.greedy_action == int(np.argmax(result.probs))
    if entropy is not None:
        assert result.task_entropy == pytest.approx(entropy, abs=ATOL)
        assert result.task_weight == pytest.approx(w_task, abs=ATOL)
        np.testing.assert_allclose(result.partner_weights, w_partners, atol=ATOL)


@pytest.mark.parametrize("method", ["sl", "nail", "aail", "aail_bounded"])
@pytest.mark.parametrize("n_partners", [0, 1, 2, 3, 4])
def test_engine_matches_naive_reference(tiny_zoo, method: str, n_partners: int) -> None:
    store = tiny_zoo.store
    engine = InferenceEngine(store)
    rng = np.random.default_rng(n_partners)
    # the partners alone (with 0 partners: one bystander), and a 5-agent world with bystanders
    for n_agents in sorted({max(2, 1 + n_partners), 5}):
        obs_BD = rng.random((3, 4 * n_agents))
        obs_BD[0, :2] = (0.1, 0.5)  # the ego inside its target area a2 (the guard lets it blend)
        indices = rng.permutation(np.arange(1, n_agents))[:n_partners]
        partners = [(int(i), {g: 1.0}) for i, g in zip(indices, PARTNER_GOALS, strict=False)]
        results = engine.act(
            ActRequest("particle", "a2", obs_BD, _specs(partners), method=method)  # type: ignore[arg-type]
        )
        assert len(results) == 3
        for row, result in zip(obs_BD, results, strict=True):
            _check_row(result, reference(store, row, "a2", partners, method, tiny_zoo.alpha))
            assert result.method == method


def test_the_progress_guard_blends_only_inside_the_target(tiny_zoo) -> None:
    """aail_bounded with a bound too loose to matter: AAIL where the ego is inside its target
    area, SL's policy where it is not (R2, `policy.regret_bound`)."""
    engine = InferenceEngine(tiny_zoo.store)
    obs_BD = np.array([[0.1, 0.5, 0, 0, 0.7, 0.6, 0, 0], [0.6, 0.5, 0, 0, 0.7, 0.6, 0, 0]])
    partners = (PartnerSpec(1, goal="b3"),)

    def probs(method: str, **kw: float) -> np.ndarray:
        rows = engine.act(ActRequest("particle", "a2", obs_BD, partners, method=method, **kw))  # type: ignore[arg-type]
        return np.array([r.probs for r in rows])

    bounded = probs("aail_bounded", regret_bound=1e6)
    inside = reference(
        tiny_zoo.store,
        obs_BD[0],
        "a2",
        [(1, {"b3": 1.0})],
        "aail_bounded",
        tiny_zoo.alpha,
        None,
        1e6,
    )
    np.testing.assert_allclose(bounded[0], inside[0], atol=ATOL)  # R3 and R4 inside
    assert not np.allclose(bounded[0], probs("sl")[0], atol=1e-3)  # it blends there
    np.testing.assert_allclose(bounded[1], probs("sl")[1], atol=1e-12)
    assert not np.allclose(probs("aail")[1], probs("sl")[1])  # the guard made a difference
    [single] = engine.act(
        ActRequest("particle", "a2", obs_BD[1:], partners, method="aail_bounded", regret_bound=1e6)
    )
    np.testing.assert_allclose(single.probs, bounded[1], atol=1e-12)  # the single-row path too


def test_without_the_goal_oracle_the_bound_applies_on_every_row(tiny_zoo) -> None:
    """`InferenceEngine(goal_oracle=False)`: aail_bounded asks the domain nothing, so R1 with
    the default ε on every row, inside the target or not, and no R3 or R4: `policy.blend`'s
    aail_bounded on the task and impact Q-values themselves."""
    obs_BD = np.array([[0.1, 0.5, 0, 0, 0.7, 0.6, 0, 0], [0.6, 0.5, 0, 0, 0.7, 0.6, 0, 0]])
    request = ActRequest("particle", "a2", obs_BD, (PartnerSpec(1, goal="b3"),))
    rows = InferenceEngine(tiny_zoo.store, goal_oracle=False).act(request)
    with_oracle = InferenceEngine(tiny_zoo.store).act(request)
    for row, result in zip(obs_BD, rows, strict=True):
        ego, partner = row[:4], row[4:]
        q_task = _q(tiny_zoo.store, "particle/task/a2", None, row)[None]
        q_impact = _q(tiny_zoo.store, "particle/impact/b3", None, np.r_[ego, partner])[None, None]
        epsilon = DEFAULT_EPSILON_PER_ALPHA * tiny_zoo.alpha
        want = blend("aail_bounded", q_task, q_impact, tiny_zoo.alpha, regret_bound=epsilon)
        np.testing.assert_allclose(result.probs, want.probs_BA[0], atol=ATOL)
    # inside the target the oracle's R3 flattens the task Q and R4 keeps the target: not so here
    assert not np.allclose(rows[0].probs, with_oracle[0].probs, atol=1e-6)


def test_the_blend_keeps_the_reached_target(tiny_zoo) -> None:
    """R4: inside its target area, AAIL-B gives no probability to an action after which the ego
    would leave it (or coast out resting) while another action keeps it; ε = 0 is still SL."""
    from envs.particle.domain import PARTICLE

    engine = InferenceEngine(tiny_zoo.store)
    # a2 is x in [0, 0.2], y in [0.4, 0.6]: the ego at its right edge, moving right
    obs_BD = np.array([[0.17, 0.5, 0.3, 0.0, 0.7, 0.6, 0, 0], [0.1, 0.5, 0.0, 0.0, 0.7, 0.6, 0, 0]])
    kept = PARTICLE.goal_kept(obs_BD, 2, "a2")
    assert kept[0].any() and not kept[0].all() and kept[1].all()
    partners = (PartnerSpec(1, goal="b3"),)

    def act(rows: np.ndarray, **kw: float) -> np.ndarray:
        request = ActRequest("particle", "a2", rows, partners, method="aail_bounded", **kw)  # type: ignore[arg-type]
        return np.array([r.probs for r in engine.act(request)])

    bounded = act(obs_BD, regret_bound=1e6)
    aail = np.array(
        [r.probs for r in engine.act(ActRequest("particle", "a2", obs_BD, partners, method="aail"))]
    )
    assert np.all(bounded[0][~kept[0]] == 0.0) and aail[0][~kept[0]].sum() > 1e-3
    for row, probs in zip(obs_BD, bounded, strict=True):  # R3 (flat task Q), then R4
        ref = reference(
            tiny_zoo.store, row, "a2", [(1, {"b3": 1.0})], "aail_bounded", tiny_zoo.alpha, None, 1e6
        )
        np.testing.assert_allclose(probs, ref[0], atol=ATOL)
    np.testing.assert_allclose(act(obs_BD[:1], regret_bound=1e6)[0], bounded[0], atol=1e-12)
    sl = np.array(
        [r.probs for r in engine.act(ActRequest("particle", "a2", obs_BD, partners, method="sl"))]
    )
    np.testing.assert_allclose(act(obs_BD, regret_bound=0.0), sl, atol=1e-12)


def test_engine_single_agent_uses_the_phantom(tiny_zoo) -> None:
    engine = InferenceEngine(tiny_zoo.store)
    obs = np.array([[0.2, 0.9, 0.1, -0.1]])
    [result] = engine.act(ActRequest("particle", "c", obs, method="aail"))
    _check_row(result, reference(tiny_zoo.store, obs[0], "c", [], "aail", tiny_zoo.alpha))
    assert result.task_weight == 1.0 and result.partner_weights == []


@pytest.mark.parametrize("method", ["nail", "aail", "aail_bounded"])
def test_engine_goal_distributions(tiny_zoo, method: str) -> None:
    engine = InferenceEngine(tiny_zoo.store)
    obs_BD = np.random.default_rng(5).random((4, 16))
    partners = [
        (3, {"b3": 0.7, "c": 0.3}),
        (1, {"d4": 1.0}),
        (2, {"e0": 0.25, "b3": 0.75, "c1": 0.0}),
    ]
    results = engine.act(ActRequest("particle", "a2", obs_BD, _specs(partners), method=method))  # type: ignore[arg-type]
    kept = [(i, {g: p for g, p in goals.items() if p > 0}) for i, goals in partners]
    for row, result in zip(obs_BD, results, strict=True):
        _check_row(result, reference(tiny_zoo.store, row, "a2", kept, method, tiny_zoo.alpha))
    used = [(m.role, m.goal, m.partner_index) for m in results[0].models]
    assert used == [
        ("task", "a2", None),
        ("impact", "b3", 3),
        ("impact", "c", 3),
        ("impact", "d4", 1),
        ("impact", "e0", 2),
        ("impact", "b3", 2),
    ]  # goals with probability 0 are not loaded


@pytest.mark.parametrize("combo", [("b3",), ("b3", "c1")])
def test_engine_joint_learner(tiny_zoo, combo: tuple[str, ...]) -> None:
    engine = InferenceEngine(tiny_zoo.store)
    n_agents = 1 + len(combo)
    obs_BD = np.random.default_rng(1).random((2, 4 * n_agents))
    partners = [(i + 1, {g: 1.0}) for i, g in enumerate(combo)][::-1]  # given out of index order
    results = engine.act(ActRequest("particle", "a2", obs_BD, _specs(partners), method="jl"))
    for row, result in zip(obs_BD, results, strict=True):
        _check_row(result, reference(tiny_zoo.store, row, "a2", partners, "jl", tiny_zoo.alpha))
        assert result.task_weight == 1.0 and result.partner_weights == [0.0] * len(combo)
    [model] = results[0].models
    assert (model.role, model.name) == ("joint", "particle/joint/" + "+".join(["a2", *combo]))


def test_temperature_from_request_lineage_or_default(tiny_zoo) -> None:
    engine = InferenceEngine(tiny_zoo.store)
    obs = np.random.default_rng(2).random((1, 8))
    partners = [(1, {"c1": 1.0})]
    for goal, temperature, expected in (
        ("a2", 0.3, 0.3),
        ("a2", None, tiny_zoo.alpha),
        ("b3", None, 0.02),
    ):
        [result] = engine.act(
            ActRequest("particle", goal, obs, _specs(partners), temperature=temperature)
        )  # the default method, aail_bounded: ε is twice the task model's α whatever the temperature
        model_alpha = 0.02 if goal == "b3" else tiny_zoo.alpha
        ref = reference(
            tiny_zoo.store,
            obs[0],
            goal,
            partners,
            "aail_bounded",
            expected,
            regret_bound=model_alpha,
        )
        _check_row(result, ref)


def test_networks_of_different_architectures(tiny_zoo) -> None:
    """A group whose specs differ is evaluated in one stacked pass per architecture."""
    wide = QNetSpec(obs_dim=8, n_actions=5, hidden=(32, 8))
    version = tiny_zoo.register("particle/impact/c", "impact", ("c",), wide, seed=7, aliases=())
    pinned = {"particle/impact/c": version}
    engine = InferenceEngine(tiny_zoo.store)
    obs_BD = np.random.default_rng(8).random((3, 12))
    partners = [(1, {"c": 1.0}), (2, {"b3": 0.5, "c": 0.5})]
    results = engine.act(ActRequest("particle", "a2", obs_BD, _specs(partners), versions=pinned))
    for row, result in zip(obs_BD, results, strict=True):
        ref = reference(
            tiny_zoo.store, row, "a2", partners, "aail_bounded", tiny_zoo.alpha, versions=pinned
        )
        _check_row(result, ref)
    assert results[0].models[1].version == version == 2


@pytest.mark.parametrize("batch", [7, 100])  # 100 rows: the member-by-member forward
def test_batch_equals_row_by_row(tiny_zoo, batch: int) -> None:
    engine = InferenceEngine(tiny_zoo.store)
    obs_BD = np.random.default_rng(3).random((batch, 20))
    partners = _specs([(4, {"b3": 1.0}), (2, {"c": 0.4, "e0": 0.6}), (1, {"d4": 1.0})])
    batched = engine.act(ActRequest("particle", "e0", obs_BD, partners))
    for row, result in zip(obs_BD, batched, strict=True):
        [single] = engine.act(ActRequest("particle", "e0", row[None], partners))
        np.testing.assert_allclose(result.probs, single.probs, rtol=1e-5, atol=1e-8)
        assert result.greedy_action == single.greedy_action
        # float32 sums depend on the BLAS kernel chosen for the batch size: equal to ~1e-7
        assert result.task_weight == pytest.approx(single.task_weight, abs=1e-6)
        np.testing.assert_allclose(result.partner_weights, single.partner_weights, atol=1e-6)
        assert result.models == single.models


def test_seeded_sampling_is_reproducible_and_follows_probs(tiny_zoo) -> None:
    engine = InferenceEngine(tiny_zoo.store)
    obs_BD = np.repeat(np.random.default_rng(4).random((1, 8)), 4000, axis=0)
    request = ActRequest(
        "particle", "c1", obs_BD, _specs([(1, {"b3": 1.0})]), temperature=2.0, seed=11
    )
    first = [r.action for r in engine.act(request)]
    assert first == [r.action for r in engine.act(request)]
    other = ActRequest("particle", "c1", obs_BD, request.partners, temperature=2.0, seed=12)
    assert first != [r.action for r in engine.act(other)]
    probs = np.array(engine.act(request)[0].probs)
    assert probs.min() > 0.02  # a soft policy at temperature 2: every action is seen
    frequencies = np.bincount(first, minlength=5) / len(first)
    np.testing.assert_allclose(frequencies, probs, atol=0.03)
    unseeded = ActRequest("particle", "c1", obs_BD[:50], request.partners, temperature=2.0)
    assert len({tuple(r.action for r in engine.act(unseeded)) for _ in range(3)}) > 1
