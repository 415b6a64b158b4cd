"""envs.scene: whatever numbers an env's drawing hands in (numpy scalars of any width), the JSON
is plain Python numbers that any encoder takes; a number that is not one is named."""

from __future__ import annotations

import json

import numpy as np
import orjson
import pytest

from envs.scene import AgentMark, Scene, SceneFrame, circle, rect


def test_numpy_scalars_become_plain_numbers() -> None:
    scene = Scene(
        np.float64(2),
        np.float32(1.5),
        np.bool_(True),  # type: ignore[arg-type]
        np.float32(0.25),
        ("#000000",),
        (
            rect(
                np.float32(0.1), np.int64(0), np.float16(1), np.float32(1), opacity=np.float32(0.5)
            ),
        ),
    )
    frame = SceneFrame(
        (AgentMark(np.int64(0), np.float32(0.123456), np.float32(0.5), "agent 0"),),
        (circle(np.float32(1), np.float32(1), np.float32(0.1)),),
    )
    for out in (scene.to_json(), frame.to_json()):
        assert orjson.loads(orjson.dumps(out)) == json.loads(json.dumps(out))
    assert frame.to_json()["agents"][0] == {"index": 0, "x": 0.1235, "y": 0.5, "label": "agent 0"}


def test_a_number_that_is_not_one_is_named() -> None:
    with pytest.raises(ValueError, match="agent 1: x: expected a finite number"):
        SceneFrame((AgentMark(1, float("nan"), 0.0, "agent 1"),)).to_json()
    with pytest.raises(ValueError, match="shape 'wall': w: expected a number"):
        rect(0, 0, "wide", 1, label="wall").to_json()  # type: ignore[arg-type]
