"""`coexist_client.RemotePolicy` and `coexist run` against a real `coexist serve` holding particle
and kitchen networks: kitchen episodes through the server (`coexist run --env cooking`), goals
announced or inferred, the same episodes over HTTP and gRPC."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from coexist_client import Client, RemotePolicy
from console_zoo import build_console_zoo
from live_serve import serving
from replica_cluster import Server
from typer.testing import CliRunner

from cli.main import app
from envs.registry import make_env
from services.env_client import run_episodes

KITCHEN = ("TomatoLettuceSalad", "CarrotBanana")


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    folder = tmp_path_factory.mktemp("remote_policy")
    with serving(folder, build_console_zoo(folder / "models.db")) as server:
        yield server


@pytest.mark.parametrize("transport", ["http", "grpc"])
def test_coexist_run_plays_kitchen_episodes_through_the_server(
    server: Server, transport: str
) -> None:
    url = server.http_url if transport == "http" else f"grpc://{server.grpc_target}"
    result = CliRunner().invoke(
        app,
        [
            "run",
            "--server",
            url,
            "--env",
            "cooking",
            "--ego",
            KITCHEN[0],
            "--partners",
            KITCHEN[1],
            "--episodes",
            "2",
            "--max-steps",
            "25",
        ],
        env={"COLUMNS": "200"},
    )
    assert result.exit_code == 0, result.output
    assert "cooking: 2 episodes" in result.output
    assert KITCHEN[0] in result.output and KITCHEN[1] in result.output
    assert "episode length: 25.00" in result.output  # untrained cooks: truncated


@pytest.mark.parametrize("env", ["cooking", "particle"])
def test_inferred_goals_give_the_same_episodes_over_both_transports(
    server: Server, env: str
) -> None:
    goals = KITCHEN if env == "cooking" else ("a2", "b3")
    runs = []
    for url in (server.http_url, f"grpc://{server.grpc_target}"):
        with Client(url) as client:
            results = run_episodes(
                client,
                env=env,
                ego_goal=goals[0],
                partner_goals=goals[1:],
                infer=True,
                episodes=2,
                seed=3,
                max_steps=15,
            )
        runs.append([(r.returns, r.length) for r in results])
    assert runs[0] == runs[1]


def test_a_remote_policy_reports_its_belief_over_an_inferred_partner(server: Server) -> None:
    env = make_env("cooking", KITCHEN, max_steps=10)
    observations, _ = env.reset(seed=0)
    with Client(server.http_url) as client:
        cook = RemotePolicy(client, "cooking", KITCHEN, agent=1, infer=True, seed=0)
        partner = RemotePolicy(client, "cooking", KITCHEN, agent=0, method="sl", seed=1)
        actions: dict[str, int] = {}
        for _ in range(4):
            observed = {0: actions["agent_0"]} if actions else None
            actions = {
                "agent_0": partner(observations["agent_0"]),
                "agent_1": cook(observations["agent_1"], observed),
            }
            observations, *_ = env.step(actions)
        assert cook.last is not None
        (belief,) = cook.last.beliefs
        assert belief.index == 1 and belief.updates == 3
        cooking = next(e for e in client.envs() if e.name == "cooking")
        assert belief.top and {goal for goal, _ in belief.top} <= set(cooking.goals)
        cook.close()
        partner.close()


def test_a_remote_policy_refuses_an_agent_outside_the_goals() -> None:
    with pytest.raises(ValueError, match="agent"):
        RemotePolicy(Client("http://127.0.0.1:1"), "particle", ("a2", "b3"), agent=2)
