"""services.engine.validation: the check of the partners a client sends again on every call is
kept (by the tuple's identity, or by the partners' content: int indices and announced goals),
and only where nothing in it can change."""

from __future__ import annotations

import numpy as np
import pytest

from services.engine import ActRequest, InvalidRequest, PartnerSpec
from services.engine.validation import CheckedPartner, check_request

OBS_3 = np.zeros((1, 12))  # three particle agents


def _request(partners: object) -> ActRequest:
    return ActRequest("particle", "a2", OBS_3, partners)  # type: ignore[arg-type]


def test_the_same_tuple_of_announced_goals_is_checked_once() -> None:
    partners = (PartnerSpec(1, "b3"), PartnerSpec(2, "c0"))
    first, second = check_request(_request(partners), 8), check_request(_request(partners), 8)
    assert first.partners is second.partners
    other = check_request(_request((PartnerSpec(1, "b3"), PartnerSpec(2, "c0"))), 8)
    assert other.partners is first.partners  # new specs, the same content: kept by content


def test_content_decides_and_an_edited_list_is_seen() -> None:
    as_list = [PartnerSpec(1, "b3")]
    assert check_request(_request(as_list), 8).partners == (CheckedPartner(1, ("b3",), None),)
    as_list[0] = PartnerSpec(1, "zz")
    with pytest.raises(InvalidRequest, match="unknown goal"):
        check_request(_request(as_list), 8)
    as_list[0] = PartnerSpec(2, "b3")
    assert check_request(_request(as_list), 8).partners == (CheckedPartner(2, ("b3",), None),)


def test_an_index_that_only_equals_a_kept_one_is_still_refused() -> None:
    check_request(_request((PartnerSpec(1, "b3"),)), 8)  # kept: ((1, "b3"),)
    for index in (True, 1.0):  # == 1 and hash alike, yet not an integer index
        with pytest.raises(InvalidRequest, match="expected an integer"):
            check_request(_request((PartnerSpec(index, "b3"),)), 8)  # type: ignore[arg-type]


def test_goal_distributions_are_checked_every_time() -> None:
    probs = {"b3": 0.5, "c0": 0.5}
    spec = (PartnerSpec(1, goal_probs=probs),)
    check_request(_request(spec), 8)
    probs["c0"] = 0.7  # edited between calls: the next check sees it
    with pytest.raises(InvalidRequest, match="sum to"):
        check_request(_request(spec), 8)


def test_the_agent_count_is_part_of_the_check() -> None:
    partners = (PartnerSpec(2, "b3"),)
    check_request(_request(partners), 8)
    with pytest.raises(InvalidRequest, match="out of range"):
        check_request(ActRequest("particle", "a2", np.zeros((1, 8)), partners), 8)


def test_a_refused_tuple_is_refused_every_time() -> None:
    partners = (PartnerSpec(1, "zz"),)
    for _ in range(2):
        with pytest.raises(InvalidRequest, match="unknown goal"):
            check_request(_request(partners), 8)
