"""The PettingZoo env and the gymnasium single-agent wrapper: conformance, spaces, options, infos,
errors, rendering, the registry entry."""

import functools
from pathlib import Path

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from pettingzoo.test import parallel_api_test, parallel_seed_test
from PIL import Image

from envs.cooking.env import CookingEnv, parallel_env
from envs.cooking.render import render_frame, save_gif
from envs.cooking.scripted import ScriptedCook
from envs.cooking.single import CookingSingleAgentEnv
from envs.registry import get_domain, known_envs, make_env

CASES = {
    "coexistence": ("TomatoLettuceSalad", "CarrotBanana"),
    "open": ("OnionSoup", "BananaSmoothie"),
    "split": ("ChoppedTomato", "CarrotBanana"),
}


@pytest.mark.parametrize("layout", sorted(CASES))
def test_pettingzoo_conformance(layout: str) -> None:
    make = functools.partial(parallel_env, layout=layout, recipes=CASES[layout], random_starts=True)
    parallel_api_test(make(), num_cycles=500)
    parallel_seed_test(make)


def test_spaces_infos_and_start_state_option() -> None:
    env = CookingEnv()
    obs, infos = env.reset(seed=0)
    assert env.possible_agents == ["agent_0", "agent_1"]
    assert env.observation_space("agent_1").shape == (188,) and env.action_space("agent_0").n == 5
    assert infos == {
        "agent_0": {"recipe": "TomatoLettuceSalad", "delivered": False},
        "agent_1": {"recipe": "CarrotBanana", "delivered": False},
    }
    np.testing.assert_array_equal(env.state(), obs["agent_0"])
    start = env.world.state
    start.agent_rc[0, 0] = (3, 4)
    obs, _ = env.reset(options={"state": start})
    assert env.world.state.agent_rc[0, 0].tolist() == [3, 4]
    assert obs["agent_0"][1] == 4 / 16


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"recipes": ("ChoppedTomato",)}, "one recipe per agent"),
        ({"recipes": "ChoppedTomato"}, "one recipe per agent"),
        ({"recipes": ("Pizza", "ChoppedTomato")}, "Pizza"),
        ({"recipes": ("OnionSoup", "ChoppedTomato")}, "onion, blender"),
        ({"layout": "galley"}, "galley"),
        ({"render_mode": "human"}, "render_mode"),
    ],
)
def test_bad_construction(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        CookingEnv(**kwargs)


def test_bad_reset_and_step_input() -> None:
    env = CookingEnv()
    with pytest.raises(ValueError, match="state"):
        env.reset(options={"state": np.zeros((2, 2))})
    env.reset(seed=0)
    with pytest.raises(ValueError, match="agent_1"):
        env.step({"agent_0": 0})
    with pytest.raises(ValueError, match="actions"):
        env.step({"agent_0": 0, "agent_1": 9})


def test_truncation_ends_the_episode() -> None:
    env = CookingEnv(max_steps=3)
    env.reset(seed=0)
    for _ in range(2):
        _, rewards, _, truncated, _ = env.step({"agent_0": 0, "agent_1": 0})
        assert not any(truncated.values()) and rewards == {"agent_0": -0.01, "agent_1": -0.01}
    _, _, terminated, truncated, _ = env.step({"agent_0": 0, "agent_1": 0})
    assert all(truncated.values()) and not any(terminated.values()) and env.agents == []
    with pytest.raises(ValueError, match="reset"):
        env.step({"agent_0": 0, "agent_1": 0})


@pytest.mark.filterwarnings("ignore:.*alternative render modes")
def test_gymnasium_single_agent_wrapper() -> None:
    env = CookingSingleAgentEnv(layout="open", recipes=("ChoppedTomato", "BananaSmoothie"))
    check_env(env, skip_render_check=True)
    helped = CookingSingleAgentEnv(
        recipes=("TomatoLettuceSalad", "CarrotBanana"),
        agent=1,
        partners={0: ScriptedCook("TomatoLettuceSalad", handover="carrot")},
        render_mode="rgb_array",
    )
    check_env(helped)
    obs, info = helped.reset(seed=0)
    assert obs.shape == (188,) and info == {"recipe": "CarrotBanana", "delivered": False}
    for _ in range(30):  # the controlled right cook stands still; the scripted left cook works
        obs, reward, terminated, truncated, _ = helped.step(0)
    assert reward == pytest.approx(-0.01) and not terminated and not truncated
    assert helped.env.world.state.obj_state[0].max() > 0  # the partner chopped something
    with pytest.raises(ValueError, match="action"):
        helped.step(7)
    with pytest.raises(ValueError, match="partners"):
        CookingSingleAgentEnv(agent=0, partners={0: ScriptedCook("ChoppedTomato")})
    with pytest.raises(ValueError, match="agent"):
        CookingSingleAgentEnv(agent=2)


def test_render_and_gif(tmp_path: Path) -> None:
    env = CookingEnv(layout="open", recipes=("OnionSoup", "CarrotBanana"), render_mode="rgb_array")
    env.reset(seed=0)
    frames = [env.render()]
    rng = np.random.default_rng(0)
    for _ in range(20):
        env.step({a: int(rng.integers(5)) for a in env.agents})
        frames.append(env.render())
    frame = frames[-1]
    assert frame is not None and frame.shape == (7 * 48 + 2 * 16, 11 * 48, 3)
    assert frame.dtype == np.uint8 and len(np.unique(frame.reshape(-1, 3), axis=0)) > 10
    small = render_frame(env.layout, env.world.state, env.recipes, cell=16)
    assert small.shape == (7 * 16 + 32, 11 * 16, 3)
    path = save_gif([f for f in frames if f is not None], tmp_path / "episode.gif", fps=8)
    n_frames = getattr(Image.open(path), "n_frames", 1)
    assert 2 <= n_frames <= len(frames)  # Pillow merges repeated frames
    with pytest.warns(UserWarning, match="render_mode"):
        assert CookingEnv().render() is None
    with pytest.raises(ValueError, match="cell"):
        render_frame(env.layout, env.world.state, env.recipes, cell=4)


def test_registry_entry() -> None:
    assert "cooking" in known_envs()
    assert get_domain("cooking").goals[1] == "TomatoLettuceSalad"
    env = make_env("cooking", ("TomatoLettuceSalad", "CarrotBanana"), layout="coexistence")
    assert isinstance(env, CookingEnv) and env.recipes == ("TomatoLettuceSalad", "CarrotBanana")
