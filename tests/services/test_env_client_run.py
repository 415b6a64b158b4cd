"""The environment client end to end against real in-process servers (gRPC and uvicorn): the same
episodes over both transports, equal to a naive loop over the engine, and the `coexist run` CLI."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from coexist_client import CoexistClient, GrpcCoexistClient
from grpc_live_server import LiveServer, live_grpc_server
from http_live_server import inference_app, live_http_server
from PIL import Image
from typer.testing import CliRunner

from cli.main import app
from envs.particle.env import ParticleCoexistenceEnv
from envs.particle.scenarios import start_states
from model_store.sql import SqlModelStore
from services.engine import ActRequest, InferenceEngine, PartnerSpec
from services.engine.messages import DEFAULT_METHOD
from services.env_client import EpisodeResult, agent_seed, mean_se, run_episodes, summarise

GOALS = ("a2", "b3", "c")  # ego a2, partners b3 and c


@pytest.fixture(scope="module")
def servers(_tiny_zoo_template: Any) -> Iterator[tuple[LiveServer, str]]:
    with (
        SqlModelStore(f"sqlite:///{_tiny_zoo_template}") as store,
        live_grpc_server(store) as live,
        live_http_server(inference_app(InferenceEngine(store))) as url,
    ):
        yield live, url


def reference_episode(engine: InferenceEngine, episode: int, seed: int, steps: int) -> tuple:
    """The documented protocol, written out naively: the ego with the server's default blend
    (AAIL-B) and every partner announced,
    partner j its own task policy on its own observation, agent i's step t seeded s_i + t."""
    env = ParticleCoexistenceEnv(goals=GOALS, max_steps=steps)
    obs, infos = env.reset(options={"state": start_states(seed, 2, len(GOALS))[episode]})
    partners = (PartnerSpec(1, goal=GOALS[1]), PartnerSpec(2, goal=GOALS[2]))
    returns, t = np.zeros(len(GOALS)), 0
    while env.agents:
        actions = {}
        for i, agent in enumerate(env.possible_agents):
            request = ActRequest(
                "particle",
                GOALS[i],
                obs[agent][None],
                partners if i == 0 else (),
                method=DEFAULT_METHOD if i == 0 else "sl",
                seed=agent_seed(seed, episode, i) + t,
            )
            actions[agent] = engine.act(request)[0].action
        obs, rewards, _, _, infos = env.step(actions)
        returns += [rewards[a] for a in env.possible_agents]
        t += 1
    return tuple(returns.tolist()), tuple(infos[a]["in_target"] for a in env.possible_agents), t


def test_both_transports_run_the_documented_episodes(servers: tuple[LiveServer, str]) -> None:
    live, url = servers
    kwargs: dict[str, Any] = {
        "ego_goal": GOALS[0],
        "partner_goals": GOALS[1:],
        "episodes": 2,
        "seed": 3,
        "max_steps": 6,
    }
    seen: list[EpisodeResult] = []
    with GrpcCoexistClient(live.target) as grpc_client:
        by_grpc = run_episodes(grpc_client, record_first=True, on_episode=seen.append, **kwargs)
    with CoexistClient(url) as http_client:
        by_http = run_episodes(http_client, **kwargs)
    assert seen == by_grpc
    for e, (a, b) in enumerate(zip(by_grpc, by_http, strict=True)):
        assert (a.returns, a.success, a.length) == (b.returns, b.success, b.length)
        returns, success, length = reference_episode(live.engine, e, seed=3, steps=6)
        assert a.returns == pytest.approx(returns, abs=1e-12)
        assert (a.success, a.length) == (success, length)
        assert a.goals == GOALS and a.team_return == pytest.approx(sum(returns))
    assert len(by_grpc[0].frames) == by_grpc[0].length + 1 and by_grpc[1].frames == ()
    assert by_grpc[0].frames[0].shape == (480, 480, 3)


def test_summary_statistics() -> None:
    assert mean_se([1.0, 3.0]).mean == 2.0
    assert mean_se([1.0, 3.0]).se == pytest.approx(np.std([1.0, 3.0], ddof=1) / np.sqrt(2))
    assert mean_se([5.0]).se == 0.0
    results = [
        EpisodeResult(0, ("a2", "b3"), (-1.0, -3.0), (True, False), 10),
        EpisodeResult(1, ("a2", "b3"), (-2.0, -5.0), (False, False), 20),
    ]
    summary = summarise(results)
    assert [r.mean for r in summary.returns] == [-1.5, -4.0]
    assert summary.success_rate == (0.5, 0.0)
    assert summary.team_return.mean == -5.5 and summary.length.mean == 15.0


def test_cli_run_prints_the_table_and_writes_the_gif(
    servers: tuple[LiveServer, str], tmp_path: Path
) -> None:
    live, url = servers
    gif = tmp_path / "episode.gif"
    runner = CliRunner()
    result = runner.invoke(
        app,
        [
            "run",
            "--server",
            f"grpc://{live.target}",
            "--ego",
            "a2",
            "--partners",
            "b3,c",
            "--episodes",
            "2",
            "--max-steps",
            "4",
            "--seed",
            "1",
            "--gif",
            str(gif),
        ],
    )
    assert result.exit_code == 0, result.output
    for text in ("agent_0 (ego)", "agent_2", "team", "±", "episode length"):
        assert text in result.output
    with Image.open(gif) as image:
        assert getattr(image, "n_frames", 1) == 5  # the start plus 4 steps

    over_http = runner.invoke(
        app, ["run", "--server", url, "--partners", "b3", "--episodes", "1", "--max-steps", "3"]
    )
    assert over_http.exit_code == 0, over_http.output

    bad = runner.invoke(app, ["run", "--server", url, "--ego", "zz", "--episodes", "1"])
    assert bad.exit_code == 1 and "ego_goal" in bad.output
