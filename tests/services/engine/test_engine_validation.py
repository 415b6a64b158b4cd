"""Every bad input is an `InvalidRequest` naming its field (never a crash or a NaN result)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from services.engine import (
    ActRequest,
    InferenceEngine,
    InvalidRequest,
    PartnerSpec,
    observations_from_states,
)

OBS_3 = np.random.default_rng(0).random((2, 12))  # two rows, three agents


def _request(**overrides: Any) -> ActRequest:
    fields: dict[str, Any] = {
        "env": "particle",
        "ego_goal": "a2",
        "observations": OBS_3,
        "partners": (PartnerSpec(1, goal="b3"), PartnerSpec(2, goal="c1")),
    }
    fields.update(overrides)
    return ActRequest(**fields)


def _with_row(value: float, row: int = 1, col: int = 3) -> np.ndarray:
    obs = OBS_3.copy()
    obs[row, col] = value
    return obs


CASES: list[tuple[str, dict[str, Any], str, str]] = [
    ("unknown env", {"env": "mujoco"}, "env", "unknown environment"),
    ("env not a string", {"env": ["particle"]}, "env", "unknown environment"),
    ("unknown ego goal", {"ego_goal": "z9"}, "ego_goal", "unknown goal"),
    ("unhashable ego goal", {"ego_goal": ["a2"]}, "ego_goal", "unknown goal"),
    (
        "unhashable partner goal",
        {"partners": (PartnerSpec(1, goal=["b3"]),)},  # type: ignore[arg-type]
        "partners[0].goal",
        "unknown goal",
    ),
    ("unhashable method", {"method": ["aail"]}, "method", "unknown method"),
    ("unhashable alias", {"alias": ["production"]}, "alias", "must match"),
    ("unknown method", {"method": "greedy"}, "method", "unknown method"),
    ("1-D observations", {"observations": OBS_3[0]}, "observations", "shape (B, obs_dim)"),
    (
        "ragged observations",
        {"observations": [[0.1] * 8, [0.1] * 4]},
        "observations",
        "array of numbers",
    ),
    ("strings", {"observations": np.array([["a"] * 8])}, "observations", "array of numbers"),
    ("empty batch", {"observations": np.zeros((0, 12))}, "observations", "empty batch"),
    ("length fits no N", {"observations": np.zeros((1, 10))}, "observations[0]", "length 10"),
    ("length > max agents", {"observations": np.zeros((2, 24))}, "observations", "length 24"),
    ("NaN", {"observations": _with_row(np.nan)}, "observations[1]", "NaN or inf"),
    ("inf", {"observations": _with_row(-np.inf, row=0)}, "observations[0]", "NaN or inf"),
    ("beyond float32", {"observations": _with_row(1e300)}, "observations[1]", "float32"),
    (
        "partner index 0",
        {"partners": (PartnerSpec(0, goal="b3"),)},
        "partners[0].index",
        "out of range",
    ),
    (
        "partner index N",
        {"partners": (PartnerSpec(1, goal="b3"), PartnerSpec(3, goal="c"))},
        "partners[1].index",
        "expected 1..2",
    ),
    (
        "partner index float",
        {"partners": (PartnerSpec(1.0, goal="b3"),)},  # type: ignore[arg-type]
        "partners[0].index",
        "integer",
    ),
    (
        "partner index bool",
        {"partners": (PartnerSpec(True, goal="b3"),)},
        "partners[0].index",
        "integer",
    ),
    (
        "duplicate partner",
        {"partners": (PartnerSpec(2, goal="b3"), PartnerSpec(2, goal="c"))},
        "partners[1].index",
        "twice",
    ),
    (
        "partner in a 1-agent world",
        {"observations": np.zeros((1, 4)), "partners": (PartnerSpec(1, goal="b3"),)},
        "partners[0].index",
        "only the ego",
    ),
    ("neither goal nor probs", {"partners": (PartnerSpec(1),)}, "partners[0].goal", "exactly one"),
    (
        "both goal and probs",
        {"partners": (PartnerSpec(1, goal="b3", goal_probs={"b3": 1.0}),)},
        "partners[0].goal",
        "exactly one",
    ),
    (
        "unknown partner goal",
        {"partners": (PartnerSpec(1, goal="q"),)},
        "partners[0].goal",
        "unknown goal",
    ),
    (
        "probs: unknown goal",
        {"partners": (PartnerSpec(1, goal_probs={"b3": 0.5, "q": 0.5}),)},
        "partners[0].goal_probs",
        "unknown goal",
    ),
    (
        "probs: negative",
        {"partners": (PartnerSpec(1, goal_probs={"b3": 1.5, "c": -0.5}),)},
        "partners[0].goal_probs",
        ">= 0",
    ),
    (
        "probs: NaN",
        {"partners": (PartnerSpec(1, goal_probs={"b3": float("nan")}),)},
        "partners[0].goal_probs",
        "finite",
    ),
    (
        "probs: sum",
        {"partners": (PartnerSpec(1, goal="c"), PartnerSpec(2, goal_probs={"b3": 0.5, "c": 0.49}))},
        "partners[1].goal_probs",
        "sum to 0.99",
    ),
    (
        "probs: sum overflows",
        {"partners": (PartnerSpec(1, goal_probs={"b3": 1e308, "c": 1e308}),)},
        "partners[0].goal_probs",
        "sum to inf",
    ),
    (
        "probs: empty",
        {"partners": (PartnerSpec(1, goal_probs={}),)},
        "partners[0].goal_probs",
        "non-empty",
    ),
    (
        "probs: not numbers",
        {"partners": (PartnerSpec(1, goal_probs={"b3": "1"}),)},  # type: ignore[dict-item]
        "partners[0].goal_probs",
        "finite",
    ),
    ("partners not a list", {"partners": "b3"}, "partners", "list"),
    (
        "partner not a spec",
        {"partners": ({"index": 1, "goal": "b3"},)},
        "partners[0]",
        "PartnerSpec",
    ),
    ("temperature 0", {"temperature": 0.0}, "temperature", "> 0"),
    ("temperature < 0", {"temperature": -1.0}, "temperature", "> 0"),
    ("temperature inf", {"temperature": float("inf")}, "temperature", "finite"),
    ("temperature NaN", {"temperature": float("nan")}, "temperature", "finite"),
    ("temperature string", {"temperature": "hot"}, "temperature", "finite"),
    ("regret bound < 0", {"method": "aail_bounded", "regret_bound": -1.0}, "regret_bound", ">= 0"),
    (
        "regret bound inf",
        {"method": "aail_bounded", "regret_bound": float("inf")},
        "regret_bound",
        "finite",
    ),
    ("regret bound NaN", {"regret_bound": float("nan")}, "regret_bound", "finite"),
    ("regret bound string", {"regret_bound": "tight"}, "regret_bound", "finite"),
    (
        "regret bound with aail",
        {"method": "aail", "regret_bound": 0.1},
        "regret_bound",
        "aail_bounded only",
    ),
    ("seed < 0", {"seed": -1}, "seed", ">= 0"),
    ("seed float", {"seed": 1.5}, "seed", "integer"),
    ("bad alias", {"alias": "Prod!"}, "alias", "must match"),
    (
        "pinned version 0",
        {"versions": {"particle/task/a2": 0}},
        "versions[particle/task/a2]",
        ">= 1",
    ),
    (
        "pinned version huge",
        {"versions": {"particle/task/a2": 2**70}},
        "versions[particle/task/a2]",
        "<=",
    ),
    ("versions not a mapping", {"versions": [1]}, "versions", "mapping"),
    ("jl without partners", {"method": "jl", "partners": ()}, "partners", "at least one"),
    (
        "jl with goal_probs",
        {"method": "jl", "partners": (PartnerSpec(1, goal_probs={"b3": 1.0}),)},
        "partners[0].goal_probs",
        "announced goal",
    ),
    (
        "jl with a bystander",
        {"method": "jl", "partners": (PartnerSpec(1, goal="b3"),)},
        "observations",
        "joint network",
    ),
]


@pytest.mark.parametrize(
    ("overrides", "field", "text"), [c[1:] for c in CASES], ids=[c[0] for c in CASES]
)
def test_invalid_request_names_the_field(tiny_zoo, overrides, field: str, text: str) -> None:
    engine = InferenceEngine(tiny_zoo.store)
    with pytest.raises(InvalidRequest) as err:
        engine.act(_request(**overrides))
    assert err.value.field == field
    assert text in err.value.message
    assert str(err.value).startswith(f"{field}: ")


def test_oversized_batch(tiny_zoo) -> None:
    engine = InferenceEngine(tiny_zoo.store, max_batch=3)
    assert len(engine.act(_request(observations=np.zeros((3, 12))))) == 3
    with pytest.raises(InvalidRequest, match="batch of 4 exceeds the maximum 3") as err:
        engine.act(_request(observations=np.zeros((4, 12))))
    assert err.value.field == "observations"


def test_not_a_request(tiny_zoo) -> None:
    with pytest.raises(InvalidRequest):
        InferenceEngine(tiny_zoo.store).act({"env": "particle"})  # type: ignore[arg-type]


def test_goal_probs_within_tolerance_and_zero_entries_are_accepted(tiny_zoo) -> None:
    engine = InferenceEngine(tiny_zoo.store)
    probs = {"b3": 0.5 + 4e-7, "c": 0.5, "a2": 0.0}
    [result, _] = engine.act(_request(partners=(PartnerSpec(2, goal_probs=probs),)))
    assert [m.goal for m in result.models] == ["a2", "b3", "c"]  # the 0 entry loads nothing


def test_observations_from_states() -> None:
    state = np.array([[0.1, 0.2, 0.0, 0.0], [0.3, 0.4, 0.1, 0.0], [0.5, 0.6, 0.0, 0.2]])
    obs = observations_from_states("particle", [state], 1)
    np.testing.assert_array_equal(obs, [np.r_[state[1], state[0], state[2]]])
    bad = [
        (([state], 3), "ego_index", "0..2"),
        (([state], True), "ego_index", "integer"),
        (([state[:, :3]], 0), "states", "shape"),
        (([np.zeros((6, 4))], 0), "states", "1..5 agents"),
        (([state, state[:2]], 0), "states", "equal-length"),
        (([state, np.full((3, 4), np.inf)], 0), "states[1]", "NaN or inf"),
        (([], 0), "states", "B >= 1"),
    ]
    for (states, ego), field, text in bad:
        with pytest.raises(InvalidRequest) as err:
            observations_from_states("particle", states, ego)
        assert (err.value.field, text in err.value.message) == (field, True), err.value
    with pytest.raises(InvalidRequest) as err:
        observations_from_states("atari", [state], 0)
    assert err.value.field == "env"


def _goal_probs_outcome(probs: dict[Any, Any]) -> tuple[Any, ...]:
    from services.engine import validation

    runtime = validation.env_runtime("particle")
    try:
        return ("ok", validation._check_goal_probs(probs, runtime, "f"))
    except InvalidRequest as err:
        return ("error", err.field, err.message)


def test_goal_probs_whole_collection_checks_equal_the_per_goal_loop(monkeypatch) -> None:
    """The fast check of a usual distribution (35 floats) answers as the per-goal loop does:
    the same goals and bits when clean, the same error otherwise (it defers to the loop)."""
    from envs.particle.goals import GOAL_IDS
    from services.engine import validation

    rng = np.random.default_rng(9)
    cases: list[dict[Any, Any]] = []
    for _ in range(200):
        goals = list(rng.choice(GOAL_IDS, int(rng.integers(1, len(GOAL_IDS) + 1)), False))
        cases.append(dict(zip(goals, rng.dirichlet(np.ones(len(goals))).tolist(), strict=True)))
    cases += [
        {"b3": 0.5 + 4e-7, "c": 0.5},
        {"b3": 0.5, "c": 0.5, "a2": 0.0},  # a zero: the loop drops it
        {"b3": np.float64(0.5), "c": 0.5},  # numpy floats: the loop
        {"b3": 1, "c": 0.0},  # an int
        {"b3": 0.5, "c": float("nan")},
        {"b3": float("inf"), "c": 0.5},
        {"b3": 1e308, "c": 1e308},  # fsum overflows
        {"b3": 0.5, "zz": 0.5},
        {"b3": 0.6, "c": 0.6},
        {"b3": 1.5, "c": -0.5},
        {3: 1.0},
    ]
    fast = [_goal_probs_outcome(c) for c in cases]
    monkeypatch.setattr(validation, "_clean_goal_probs", lambda probs, runtime: None)
    assert fast == [_goal_probs_outcome(c) for c in cases]
    assert sum(o[0] == "ok" for o in fast) >= 200
