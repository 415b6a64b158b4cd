"""The conformance check of an environment's registration: what coexist relies on beyond types.

    coexist env check NAME                        # the command
    from envs.check import assert_env_conforms    # a plugin's own test:
    assert_env_conforms(ENV)                      #   AssertionError listing every failure

Each check below names the method it found at fault:

| check          | what                                                                      |
|----------------|---------------------------------------------------------------------------|
| `domain`       | the domain's fields: goals, action meanings, agent counts, sizes, layouts |
| `pettingzoo`   | PettingZoo's own `parallel_api_test` on `make_env` (2 agents)            |
| `observations` | observations of every agent count have the domain's `obs_dim(n)` floats  |
| `views`        | `task_views` (B, n-1, pair_obs_dim) and `partner_view` (B, pair_obs_dim), floats |
| `perspective`  | partner view of i = task view of the partner (paper §3.2), on real states |
| `goals`        | every goal makes an env, names a model, and `goal_reached` / `goal_kept` answer in shape |
| `episodes`     | seeded episodes with random actions: finite rewards, an end within `max_steps`, the same seed the same episode |
| `drawing`      | the scene and each frame as JSON (the console streams it)               |
| `state input`  | the state adapter's observations match the env's layout (when given)    |
| `training`     | the registration's `training` resolves to numbers or a trainer          |

The episodes are played on agent counts 1..min(max_agents, 3), with goals drawn from the
combinations `make_env` takes (it may refuse some with a ValueError: a kitchen without a blender
cannot host a smoothie, a layout for two cooks a third one).
"""

from __future__ import annotations

import contextlib
import io
import itertools
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
import orjson

from envs.registry import EnvPlugin, PlainDrawing, env_plugin, load_reference

MAX_CHECKED_AGENTS = 3
EPISODE_STEPS = 50
BATCH = 4  # rows of the views checked at once
COMBOS_TRIED = 64  # goal combinations tried per agent count (`_Probe.playable`)


class CheckFailed(Exception):
    """One check's failure; the message names the method at fault."""


@dataclass(frozen=True)
class CheckResult:
    name: str
    passed: bool
    message: str  # what was checked, or why it failed ("skipped: ..." where it could not run)


def check_env(plugin: EnvPlugin | str, *, episodes: int = 3, seed: int = 0) -> list[CheckResult]:
    """Every check of the module docstring on `plugin` (a registration, or a registered name)."""
    if isinstance(plugin, str):
        plugin = env_plugin(plugin)
    probe = _Probe(plugin, episodes=episodes, seed=seed)
    results = []
    for name, check in probe.checks():
        try:
            message = check()
        except CheckFailed as failure:
            results.append(CheckResult(name, False, str(failure)))
        except Exception as exc:  # the env's own code raised: name the check and the error
            results.append(CheckResult(name, False, f"raised {type(exc).__name__}: {exc}"))
        else:
            results.append(CheckResult(name, True, message))
    return results


def assert_env_conforms(plugin: EnvPlugin | str, *, episodes: int = 3, seed: int = 0) -> None:
    """The pytest helper: AssertionError listing every failed check, one per line."""
    failed = [r for r in check_env(plugin, episodes=episodes, seed=seed) if not r.passed]
    if failed:
        lines = "\n".join(f"- {r.name}: {r.message}" for r in failed)
        raise AssertionError(f"the environment does not conform:\n{lines}")


def _expect(condition: bool, message: str) -> None:
    if not condition:
        raise CheckFailed(message)


def _is_float_array(value: Any) -> bool:
    return isinstance(value, np.ndarray) and np.issubdtype(value.dtype, np.floating)


def _described(value: Any) -> str:
    if isinstance(value, np.ndarray):
        return f"an array of shape {value.shape} and dtype {value.dtype}"
    return f"{type(value).__name__}"


class _Probe:
    """The checks of one registration, sharing the episodes they play."""

    def __init__(self, plugin: EnvPlugin, *, episodes: int, seed: int) -> None:
        self.plugin, self.domain = plugin, plugin.domain
        self.episodes, self.seed = episodes, seed
        self.rng = np.random.default_rng(seed)
        self._playable: dict[int, list[tuple[str, ...]]] = {}

    def checks(self) -> list[tuple[str, Callable[[], str]]]:
        checks = [
            ("domain", self.check_domain),
            ("pettingzoo", self.check_pettingzoo),
            ("observations", self.check_observations),
            ("views", self.check_views),
            ("perspective", self.check_perspective),
            ("goals", self.check_goals),
            ("episodes", self.check_episodes),
            ("drawing", self.check_drawing),
        ]
        if self.plugin.state_adapter is not None:
            checks.append(("state input", self.check_state_input))
        checks.append(("training", self.check_training))
        return checks

    # --- helpers -------------------------------------------------------------------------
    def playable(self, n_agents: int) -> list[tuple[str, ...]]:
        """Goal combinations of `n_agents` that `make_env` takes with its defaults (an env may
        refuse some with a ValueError: a kitchen without a blender, a layout for two cooks);
        empty where it takes none."""
        if n_agents not in self._playable:
            goals, found = self.domain.goals, []
            combos = itertools.product(goals, repeat=n_agents)
            for combo in itertools.islice(combos, COMBOS_TRIED):
                try:
                    self.plugin.make_env(goals=combo, max_steps=EPISODE_STEPS)
                except ValueError:
                    continue
                found.append(combo)
            self._playable[n_agents] = found
        return self._playable[n_agents]

    def agent_counts(self) -> list[int]:
        """The agent counts checked: 1..min(max_agents, 3) that `make_env` can host."""
        counts = [
            n
            for n in range(1, min(int(self.domain.max_agents), MAX_CHECKED_AGENTS) + 1)
            if self.playable(n)
        ]
        _expect(2 in counts, "make_env: takes no combination of two goals (raises ValueError)")
        return counts

    def goals_for(self, n_agents: int) -> tuple[str, ...]:
        combos = self.playable(n_agents)
        _expect(bool(combos), f"make_env: takes no combination of {n_agents} goals")
        return combos[int(self.rng.integers(len(combos)))]

    def make(self, goals: tuple[str, ...]) -> Any:
        try:
            return self.plugin.make_env(goals=goals, max_steps=EPISODE_STEPS)
        except Exception as exc:
            raise CheckFailed(
                f"make_env(goals={list(goals)}, max_steps={EPISODE_STEPS}) raised "
                f"{type(exc).__name__}: {exc}"
            ) from None

    def states(self, n_agents: int, episodes: int = 1) -> Iterator[dict[str, np.ndarray]]:
        """Every agent's observation (in `possible_agents` order) at each step of seeded
        random episodes."""
        for e in range(episodes):
            env = self.make(self.goals_for(n_agents))
            observations, _ = env.reset(seed=self.seed + e)
            for t in itertools.count():
                if set(env.possible_agents) <= set(observations):
                    yield {a: observations[a] for a in env.possible_agents}
                if not env.agents or t >= EPISODE_STEPS:
                    break
                actions = {a: env.action_space(a).sample() for a in env.agents}
                observations, *_ = env.step(actions)

    def observations(self, n_agents: int) -> np.ndarray:
        """Up to `BATCH` observations of agents in worlds of `n_agents`, (B, D) float32."""
        rows = [obs for o in self.states(n_agents) for obs in o.values()][:BATCH]
        return np.stack([np.asarray(r, dtype=np.float32) for r in rows])

    # --- the checks ----------------------------------------------------------------------
    def check_domain(self) -> str:
        d = self.domain
        goals = d.goals
        _expect(
            isinstance(goals, tuple) and len(goals) > 0 and all(isinstance(g, str) for g in goals),
            f"goals: expected a non-empty tuple of strings, got {goals!r:.80}",
        )
        duplicates = sorted({g for g in goals if goals.count(g) > 1})
        _expect(not duplicates, f"goals: {duplicates} appear twice")
        _expect(
            isinstance(d.action_meanings, tuple) and len(d.action_meanings) >= 1,
            f"action_meanings: expected a non-empty tuple, got {d.action_meanings!r:.80}",
        )
        _expect(d.n_actions == len(d.action_meanings), "n_actions: differs from action_meanings")
        _expect(
            isinstance(d.max_agents, int) and d.max_agents >= 2,
            f"max_agents: expected an integer >= 2 (coexistence needs a partner), got {d.max_agents!r}",
        )
        _expect(
            isinstance(d.pair_obs_dim, int) and d.pair_obs_dim >= 1,
            f"pair_obs_dim: expected a positive integer, got {d.pair_obs_dim!r}",
        )
        _expect(
            d.blend_normalisation in ("standardise", "none"),
            f"blend_normalisation: expected 'standardise' or 'none', got {d.blend_normalisation!r}",
        )
        _expect(isinstance(d.goal_is_final, bool), "goal_is_final: expected a bool")
        for n in range(1, d.max_agents + 1):
            dim = d.obs_dim(n)
            _expect(
                isinstance(dim, int) and dim >= 1,
                f"obs_dim({n}): expected a positive int, got {dim!r}",
            )
            layout = d.observation_layout(n)
            _expect(
                len(layout) == dim,
                f"observation_layout({n}): {len(layout)} names for obs_dim({n}) = {dim} features",
            )
        return f"{len(goals)} goals, {d.n_actions} actions, 1..{d.max_agents} agents"

    def check_pettingzoo(self) -> str:
        from pettingzoo.test import parallel_api_test

        env = self.make(self.goals_for(2))
        try:
            with contextlib.redirect_stdout(io.StringIO()):  # it prints its verdict
                parallel_api_test(env, num_cycles=EPISODE_STEPS)
        except Exception as exc:
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
            raise CheckFailed(
                f"PettingZoo's parallel_api_test failed ({type(exc).__name__}: {first})"
            ) from None
        return "parallel_api_test passed (2 agents)"

    def check_observations(self) -> str:
        for n in self.agent_counts():
            dim = self.domain.obs_dim(n)
            env = self.make(self.goals_for(n))
            for agent in env.possible_agents:
                shape = env.observation_space(agent).shape
                _expect(
                    shape == (dim,),
                    f"observation_space({agent!r}): shape {shape} with {n} agents, but "
                    f"obs_dim({n}) = {dim}",
                )
            for observations in self.states(n):
                for agent, obs in observations.items():
                    _expect(
                        _is_float_array(obs) and obs.shape == (dim,),
                        f"step/reset: {agent!r}'s observation is {_described(obs)} with {n} "
                        f"agents; expected ({dim},) floats (obs_dim({n}))",
                    )
                    _expect(
                        bool(np.isfinite(obs).all()),
                        f"step/reset: {agent!r}'s observation holds NaN or inf",
                    )
        return f"obs_dim(n) floats for n in {self.agent_counts()}"

    def check_views(self) -> str:
        d = self.domain
        for n in self.agent_counts():
            obs_BD = self.observations(n)
            views = d.task_views(obs_BD, n)
            expected = (len(obs_BD), max(n - 1, 1), d.pair_obs_dim)
            _expect(
                _is_float_array(views) and views.shape == expected,
                f"task_views(obs_BD, {n}): expected floats of shape {expected}, got "
                f"{_described(views)}",
            )
            for partner in range(1, n):
                view = d.partner_view(obs_BD, n, partner)
                pair = (len(obs_BD), d.pair_obs_dim)
                _expect(
                    _is_float_array(view) and view.shape == pair,
                    f"partner_view(obs_BD, {n}, {partner}): expected floats of shape "
                    f"{pair}, got {_described(view)}",
                )
        return "task_views and partner_view in shape, floating point"

    def check_perspective(self) -> str:
        d, pairs = self.domain, 0
        for n in (n for n in self.agent_counts() if n >= 2):
            for observations in self.states(n, episodes=2):
                agents = list(observations)
                for i, j in itertools.permutations(range(n), 2):
                    others_i = [a for a in range(n) if a != i]
                    others_j = [a for a in range(n) if a != j]
                    obs_i = np.asarray(observations[agents[i]], dtype=np.float32)[None]
                    obs_j = np.asarray(observations[agents[j]], dtype=np.float32)[None]
                    seen = d.partner_view(obs_i, n, others_i.index(j) + 1)[0]
                    own = d.task_views(obs_j, n)[0, others_j.index(i)]
                    _expect(
                        bool(np.allclose(seen, own, atol=1e-5)),
                        f"partner_view(obs of agent {i}, {n}, {others_i.index(j) + 1}) = "
                        f"{np.round(seen, 4).tolist()} differs from agent {j}'s own task view of "
                        f"agent {i} (task_views(obs of agent {j}, {n})[:, {others_j.index(i)}] = "
                        f"{np.round(own, 4).tolist()}): the perspective transform of paper §3.2",
                    )
                    pairs += 1
        return f"partner view = the partner's task view on {pairs} (agent, partner) states"

    def check_goals(self) -> str:
        from model_store.errors import InvalidArgument
        from model_store.naming import impact_model_name, task_model_name

        d = self.domain
        obs_BD = self.observations(2)
        playable = {g for combo in self.playable(2) for g in combo}
        for goal in d.goals:
            for make in (task_model_name, impact_model_name):
                try:
                    make(d.name, goal)
                except InvalidArgument as err:
                    raise CheckFailed(f"goals: {goal!r} cannot name a model ({err})") from None
            reached = d.goal_reached(obs_BD, 2, goal)
            _expect(
                reached is None
                or (
                    isinstance(reached, np.ndarray)
                    and reached.shape == (len(obs_BD),)
                    and reached.dtype == bool
                ),
                f"goal_reached(obs_BD, 2, {goal!r}): expected None or ({len(obs_BD)},) bool, got "
                f"{_described(reached)}",
            )
            kept = d.goal_kept(obs_BD, 2, goal)
            shape = (len(obs_BD), d.n_actions)
            _expect(
                kept is None
                or (isinstance(kept, np.ndarray) and kept.shape == shape and kept.dtype == bool),
                f"goal_kept(obs_BD, 2, {goal!r}): expected None or {shape} bool, got {_described(kept)}",
            )
        idle = [g for g in d.goals if g not in playable]
        note = f"; not in make_env's first {COMBOS_TRIED} pairs: {', '.join(idle)}" if idle else ""
        return f"{len(d.goals)} goals name models and answer goal_reached/goal_kept{note}"

    def _episode(self, goals: tuple[str, ...], seed: int) -> tuple[list[Any], int]:
        """Rewards of every step and the length of one seeded random episode."""
        env = self.make(goals)
        env.reset(seed=seed)
        rng = np.random.default_rng(seed)
        trace: list[Any] = []
        for t in range(EPISODE_STEPS + 1):
            if not env.agents:
                return trace, t
            actions = {a: int(rng.integers(env.action_space(a).n)) for a in env.agents}
            observations, rewards, *_ = env.step(actions)
            for agent, reward in rewards.items():
                _expect(
                    isinstance(reward, int | float | np.number) and math.isfinite(float(reward)),
                    f"step: {agent!r}'s reward {reward!r} is not a finite number",
                )
            trace.append(
                (
                    sorted((a, float(r)) for a, r in rewards.items()),
                    sorted((a, np.asarray(o).round(6).tobytes()) for a, o in observations.items()),
                )
            )
        raise CheckFailed(
            f"step: the episode did not end within max_steps={EPISODE_STEPS} "
            "(make_env must honour max_steps)"
        )

    def check_episodes(self) -> str:
        lengths = []
        for e in range(self.episodes):
            goals = self.goals_for(2)
            first, length = self._episode(goals, self.seed + e)
            again, _ = self._episode(goals, self.seed + e)
            _expect(
                first == again,
                f"reset(seed={self.seed + e}): the same seed and actions gave another episode "
                "(seed every random draw from reset's seed)",
            )
            lengths.append(length)
        return f"{self.episodes} seeded episodes of {lengths} steps, reproducible"

    def check_drawing(self) -> str:
        drawing = self.plugin.drawing or PlainDrawing()
        what = "the plain drawing" if self.plugin.drawing is None else type(drawing).__name__
        env = self.make(self.goals_for(2))
        env.reset(seed=self.seed)
        for method, call in (("scene", drawing.scene), ("scene_frame", drawing.scene_frame)):
            try:
                orjson.dumps(call(env).to_json())
            except Exception as exc:
                raise CheckFailed(
                    f"{method}(env) is not JSON the console can stream ({type(exc).__name__}: {exc})"
                ) from None
        for _ in range(5):
            if not env.agents:
                break
            env.step({a: env.action_space(a).sample() for a in env.agents})
            orjson.dumps(drawing.scene_frame(env).to_json())
        return f"{what}: scene and frames as JSON"

    def check_state_input(self) -> str:
        adapter = self.plugin.state_adapter
        assert adapter is not None
        n = 2
        states = self.rng.uniform(0.0, 1.0, (BATCH, n, len(adapter.features)))
        obs = adapter.observations(states)
        expected = (BATCH, n, self.domain.obs_dim(n))
        _expect(
            _is_float_array(obs) and obs.shape == expected,
            f"state_adapter.observations: expected floats of shape {expected}, got {_described(obs)}",
        )
        return f"states of {len(adapter.features)} features per agent"

    def check_training(self) -> str:
        training = self.plugin.training
        if training is None:
            return "the generic trainer with its default numbers"
        if isinstance(training, str):
            try:
                training = load_reference(training, "training")
            except ValueError as err:
                raise CheckFailed(str(err)) from None
        try:
            from trainer.generic import GenericTraining
        except ImportError:  # a server-only install: no torch
            return f"{type(training).__name__} (skipped: the trainer is not installed)"
        if isinstance(training, GenericTraining):
            return "the generic trainer with the env's numbers"
        methods = ("default_configs", "train_tasks", "train_impacts", "train_joint", "print_gates")
        missing = [m for m in methods if not callable(getattr(training, m, None))]
        _expect(
            not missing,
            f"training: a {type(training).__name__} is neither GenericTraining nor an EnvTrainer "
            f"(without {', '.join(missing)})",
        )
        return f"a trainer of its own ({type(training).__name__})"
