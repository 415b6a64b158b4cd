"""A session's settings through the codec's JSON: every belief setting comes back as it was
written (the likelihood's noise included), and equal settings give equal bytes."""

from __future__ import annotations

import pytest

from policy.belief import BeliefConfig
from services.sessions import SessionPartner, SessionSettings
from services.sessions.codec import settings_from_json, settings_json


@pytest.mark.parametrize(
    "belief",
    [
        BeliefConfig(),
        BeliefConfig(forgetting=0.8, floor=0.0, temperature=0.07, noise=0.3),
        BeliefConfig(noise=0.0),
    ],
)
def test_belief_settings_round_trip(belief: BeliefConfig) -> None:
    settings = SessionSettings(
        "particle", "a2", (SessionPartner(1, infer=True),), seed=3, belief=belief
    )
    data = settings_json(settings)
    back = settings_from_json(data)
    assert back.belief == belief
    assert back == settings
    assert settings_json(back) == data
