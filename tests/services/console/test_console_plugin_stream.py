"""The console's live episode of a plugin's environment (the corridor of tests/envs/tinyline,
registered in this process): its drawing's numpy scalars stream as JSON, and a drawing that
raises mid-episode ends the stream with an error line naming the env, not with silence."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import orjson
import pytest
from console_zoo import _register_env
from fastapi.testclient import TestClient
from pydantic import SecretStr

from envs.registry import env_plugin, register_env
from model_store.sql import SqlModelStore
from services.app import create_app
from services.settings import Settings

QUERY = {"env": "tinyline", "ego_goal": "c1", "partners": "c3", "methods": "sl,aail"}


@pytest.fixture
def client(tinyline: str, tmp_path: Path) -> Iterator[TestClient]:
    url = f"sqlite:///{tmp_path / 'models.db'}"
    with SqlModelStore(url) as store:
        _register_env(store, tinyline, 0)  # random networks for every corridor goal
    settings = Settings(
        admin_token=SecretStr("plugin-console-t0ken"),
        data_dir=tmp_path,
        store_url=url,
        grpc_enabled=False,
    )
    with TestClient(create_app(settings)) as test_client:
        yield test_client


def _lines(client: TestClient, **query: Any) -> list[dict[str, Any]]:
    answer = client.get("/v1/console/episode", params={**QUERY, **query})
    assert answer.status_code == 200, answer.text
    return [orjson.loads(line) for line in answer.content.splitlines()]


def test_the_corridor_streams_with_its_drawing(client: TestClient) -> None:
    lines = _lines(client, max_steps=8)
    assert lines[0]["type"] == "episode" and lines[-1]["type"] == "end"
    assert lines[0]["scene"]["width"] == 5.0 and len(lines[0]["scene"]["shapes"]) == 5
    frames = [x for x in lines if x["type"] == "frame"]
    assert frames and all(isinstance(a["x"], float) for a in frames[0]["lanes"][0]["agents"])


def test_a_drawing_that_raises_mid_episode_ends_with_an_error_line(
    client: TestClient, tinyline: str
) -> None:
    plugin = env_plugin(tinyline)
    calls = {"n": 0}

    class Failing:
        def scene(self, env: Any) -> Any:
            return plugin.drawing.scene(env)  # type: ignore[union-attr]

        def scene_frame(self, env: Any) -> Any:
            calls["n"] += 1
            if calls["n"] > 4:  # the first frames (checked before the answer starts) pass
                raise RuntimeError("the drawing broke")
            return plugin.drawing.scene_frame(env)  # type: ignore[union-attr]

    register_env(replace(plugin, drawing=Failing()), replace=True)
    lines = _lines(client, max_steps=50, seed=3)
    assert lines[-1]["type"] == "error", lines[-1]
    error = lines[-1]["error"]
    assert error["code"] == "internal"
    assert error["message"] == "the episode stopped: env 'tinyline' raised RuntimeError"
