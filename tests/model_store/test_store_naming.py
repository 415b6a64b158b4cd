"""Model names, aliases and refs."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from model_store.errors import InvalidArgument
from model_store.naming import (
    Ref,
    impact_model_name,
    joint_model_name,
    parse_ref,
    ref_candidates,
    task_model_name,
    validate_model_name,
)


def test_name_helpers() -> None:
    assert task_model_name("particle", "a3") == "particle/task/a3"
    assert impact_model_name("particle", "c4") == "particle/impact/c4"
    assert joint_model_name("particle", "a2", ["b3"]) == "particle/joint/a2+b3"
    assert joint_model_name("particle", "a2", ["b3", "c1"]) == "particle/joint/a2+b3+c1"


@pytest.mark.parametrize(
    ("call", "field"),
    [
        (lambda: task_model_name("Particle", "a3"), "env"),
        (lambda: task_model_name("particle", "a/3"), "goal"),
        (lambda: joint_model_name("particle", "a2", []), "partners"),
        (lambda: joint_model_name("particle", "a2", "b3"), "partners"),
        (lambda: joint_model_name("particle", "a2", ["b 3"]), "partners"),
    ],
)
def test_name_helpers_name_the_bad_field(call, field: str) -> None:
    with pytest.raises(ValueError) as err:
        call()
    assert err.value.field == field  # type: ignore[attr-defined]


@pytest.mark.parametrize(
    "name", ["", "a//b", "/a", "a/", "a/-/b", "a/b c", "x" * 201, "a/_b", "a/b@c"]
)
def test_invalid_model_names(name: str) -> None:
    with pytest.raises(InvalidArgument):
        validate_model_name(name)


def test_numeric_goals_make_valid_names_with_two_ref_readings() -> None:
    assert task_model_name("particle", "4") == "particle/task/4"
    assert ref_candidates("particle/task/4") == (
        Ref("particle/task", version=4),
        Ref("particle/task/4", alias="production"),
    )
    assert ref_candidates("particle/task/a3") == (Ref("particle/task/a3", alias="production"),)
    assert ref_candidates("particle/task/4@latest") == (Ref("particle/task/4", alias="latest"),)


def test_parse_ref_forms() -> None:
    assert parse_ref("particle/task/a3@latest") == Ref("particle/task/a3", alias="latest")
    assert parse_ref("particle/task/a3/12") == Ref("particle/task/a3", version=12)
    assert parse_ref("particle/task/a3") == Ref("particle/task/a3", alias="production")
    for bad in ("particle/task/a3/0", "particle/task/a3@", "particle/task/a3@Prod", "@latest", ""):
        with pytest.raises(InvalidArgument):
            parse_ref(bad)


_segment = st.from_regex(r"[a-z][a-z0-9_.+-]{0,8}", fullmatch=True)
_name = st.lists(_segment, min_size=1, max_size=4).map("/".join)
_alias = st.from_regex(r"[a-z][a-z0-9_-]{0,10}", fullmatch=True)


@given(name=_name, version=st.integers(1, 10**6), alias=_alias)
def test_refs_round_trip(name: str, version: int, alias: str) -> None:
    assert parse_ref(str(Ref(name, version=version))) == Ref(name, version=version)
    assert parse_ref(str(Ref(name, alias=alias))) == Ref(name, alias=alias)
