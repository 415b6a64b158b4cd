"""Live episodes for the web console: the server plays them, step by step, and describes each
step as a JSON frame; the page only draws.

    episode = LiveEpisode(engine, EpisodeSettings("particle", "a2", ("b3",), methods=("sl", "aail")))
    header = episode.header()              # settings, agents, action meanings, the static scene
    for frame in episode.frames(): ...     # one per step t = 0, 1, ... until every lane ended

An episode runs one *lane* per method: the same env (`envs.registry.make_env`), reset with the
same seed, so every lane starts from the same state. In each lane agent 0, the ego, acts through
a `services.sessions.Session` with `method` (the blend of paper eqs. 8-10, or SL, NAIL, ...);
partner j acts with its own task policy (`sl` on its own observation), as in `coexist run`
(`services.env_client`). The ego is told partner j's goal, or, for j in `inferred`, infers it
from the actions it sees j take (the session's belief).

Common random numbers: agent i samples step t's action with the seed `agent_seed(seed, 0, i) + t`
in every lane (the engine draws one uniform from it and takes the inverse CDF), so lanes differ
by policy only, never by sampling luck; a particle episode is the first episode of
`coexist run --seed SEED` with the same goals and method.

Frame t of a lane: the scene at state s_t (`envs.registry.Drawing.scene_frame`), the rewards received on the
way into s_t (zeros at t = 0), the returns so far, and, while the lane runs, each agent's action
distribution at s_t, the action it then took, and the ego's blend diagnostics (w_t, each
partner's weight, the task policy's normalised entropy, the beliefs over inferred partners'
goals). A lane's last frame is its final state without policies; after it the lane is `None`.

Errors: `InvalidRequest` naming the query field (`ego_goal`, `partners`, `infer`, `methods`,
`seed`, `max_steps`, `alias`, `temperature`), `ModelNotFound` for a missing network.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from envs.base import check_goal
from envs.registry import get_drawing, make_env
from services.engine import ActRequest, EngineError, InferenceEngine, InvalidRequest
from services.engine.environments import env_runtime
from services.env_client import agent_seed
from services.sessions import Observed, Session, SessionPartner, SessionSettings

MAX_LANES = 4
MAX_STEPS = 1000


@dataclass(frozen=True)
class EpisodeSettings:
    env: str
    ego_goal: str
    partner_goals: tuple[str, ...] = ()  # agent j = 1.. pursues partner_goals[j - 1]
    inferred: tuple[int, ...] = ()  # partners (1-based) whose goal the ego infers
    methods: tuple[str, ...] = ("aail",)  # one lane per method
    seed: int = 0
    max_steps: int = 200
    alias: str = "production"
    temperature: float | None = None  # the ego's (None: its task network's training α)

    def to_json(self) -> dict[str, Any]:
        return {
            "env": self.env,
            "ego_goal": self.ego_goal,
            "partners": list(self.partner_goals),
            "infer": list(self.inferred),
            "methods": list(self.methods),
            "seed": self.seed,
            "max_steps": self.max_steps,
            "alias": self.alias,
            "temperature": self.temperature,
        }


def check_episode(settings: EpisodeSettings) -> None:
    """`InvalidRequest` naming the first bad field (module docstring)."""
    runtime = env_runtime(settings.env)
    domain = runtime.domain
    for field, goals in (("ego_goal", (settings.ego_goal,)), ("partners", settings.partner_goals)):
        for goal in goals:
            try:
                check_goal(domain, goal, field)
            except ValueError as err:
                raise InvalidRequest(field, str(err).removeprefix(f"{field}: ")) from None
    n_agents = 1 + len(settings.partner_goals)
    if n_agents > domain.max_agents:
        raise InvalidRequest(
            "partners", f"env {domain.name!r} has at most {domain.max_agents - 1} partners"
        )
    for j in settings.inferred:
        if not 1 <= j < n_agents:
            existing = f"partners: 1..{n_agents - 1}" if n_agents > 1 else "the ego is alone"
            raise InvalidRequest("infer", f"partner {j} does not exist ({existing})")
    if len(set(settings.inferred)) != len(settings.inferred):
        raise InvalidRequest("infer", "a partner is named twice")
    methods, known = settings.methods, runtime.info.methods
    if not 1 <= len(methods) <= MAX_LANES or len(set(methods)) != len(methods):
        raise InvalidRequest("methods", f"expected 1..{MAX_LANES} distinct methods, got {methods}")
    for method in methods:
        if method not in known:
            raise InvalidRequest(
                "methods", f"unknown method {method!r} (known: {', '.join(known)})"
            )
    if not 0 <= settings.seed < 2**32:
        raise InvalidRequest("seed", f"expected an integer in 0..2^32-1, got {settings.seed}")
    if not 1 <= settings.max_steps <= MAX_STEPS:
        raise InvalidRequest("max_steps", f"expected 1..{MAX_STEPS}, got {settings.max_steps}")


def _renamed(err: EngineError) -> EngineError:
    """A session's field names -> the episode's (`method` -> `methods`, `partners[0].goal` ->
    `partners`)."""
    field = err.field or ""
    if field == "method":
        return err.renamed("methods")
    if field.startswith("partners["):
        return err.renamed("infer" if field.endswith(".infer") else "partners")
    return err


class _Lane:
    """One method's episode: its env, the ego's session, the agents' seeds, returns so far."""

    def __init__(self, engine: InferenceEngine, settings: EpisodeSettings, method: str) -> None:
        self.engine, self.settings, self.method = engine, settings, method
        self.goals = (settings.ego_goal, *settings.partner_goals)
        try:
            self.env = make_env(settings.env, self.goals, max_steps=settings.max_steps)
        except ValueError as err:  # e.g. a kitchen layout made for another number of cooks
            raise InvalidRequest("partners", str(err)) from None
        self.agents = list(self.env.possible_agents)
        self.seeds = [agent_seed(settings.seed, 0, i) for i in range(len(self.goals))]
        partners = tuple(
            SessionPartner(j, infer=True) if j in settings.inferred else SessionPartner(j, goal=g)
            for j, g in enumerate(settings.partner_goals, start=1)
        )
        session_settings = SessionSettings(
            settings.env,
            settings.ego_goal,
            partners,
            method=method,  # type: ignore[arg-type]
            temperature=settings.temperature,
            seed=self.seeds[0],
            alias=settings.alias,
        )
        try:
            self.session = Session(engine, session_settings, prefetch=False)
        except EngineError as err:
            raise _renamed(err) from None
        self.observations, _ = self.env.reset(seed=settings.seed)
        self.t = 0
        self.rewards = np.zeros(len(self.goals))
        self.returns = np.zeros(len(self.goals))
        self.actions: list[int] | None = None  # taken at s_t, once decided
        self.ended = False  # its final frame was sent

    def frame(self) -> dict[str, Any] | None:
        """Frame t (module docstring); decides the agents' actions while the lane runs."""
        if self.ended:
            return None
        out: dict[str, Any] = {
            "method": self.method,
            **get_drawing(self.settings.env).scene_frame(self.env).to_json(),
            "rewards": self.rewards.tolist(),
            "returns": self.returns.tolist(),
            "done": not self.env.agents,
        }
        if out["done"]:
            self.ended = True
            return out
        out.update(self._decide())
        return out

    def _decide(self) -> dict[str, Any]:
        observed = (
            [Observed(j, self.actions[j]) for j in self.settings.inferred] if self.actions else []
        )
        try:
            step = self.session.step(self.observations[self.agents[0]], observed)
        except EngineError as err:
            raise _renamed(err) from None
        ego = step.result
        policies: list[dict[str, Any]] = [{"index": 0, "probs": ego.probs, "action": ego.action}]
        for j, goal in enumerate(self.settings.partner_goals, start=1):
            obs = np.asarray(self.observations[self.agents[j]], dtype=np.float64)[None]
            request = ActRequest(
                env=self.settings.env,
                ego_goal=goal,
                observations=obs,
                method="sl",
                seed=self.seeds[j] + self.t,
                alias=self.settings.alias,
            )
            try:
                result = self.engine.act(request)[0]
            except EngineError as err:  # the partner's own task network: its goal is to blame
                raise err.renamed("partners") from None
            policies.append({"index": j, "probs": result.probs, "action": result.action})
        self.actions = [int(p["action"]) for p in policies]
        partner_weights = [
            {"index": j, "weight": w} for j, w in enumerate(ego.partner_weights, start=1)
        ]
        beliefs = [
            {
                "index": b.index,
                "top": [{"goal": g, "prob": p} for g, p in b.top],
                "entropy": b.entropy,
                "updates": b.updates,
            }
            for b in step.beliefs
        ]
        ego_json = {
            "task_weight": ego.task_weight,
            "task_entropy": ego.task_entropy,
            "partner_weights": partner_weights,
            "beliefs": beliefs,
        }
        if self.t == 0:
            ego_json["models"] = [f"{m.name}/{m.version}" for m in ego.models]
        return {"policies": policies, "ego": ego_json}

    def advance(self) -> None:
        """Take the decided actions: state s_t -> s_{t+1}."""
        if self.ended or not self.env.agents or self.actions is None:
            return
        actions = dict(zip(self.agents, self.actions, strict=True))
        self.observations, rewards, _, _, _ = self.env.step(actions)
        self.rewards = np.array([rewards[a] for a in self.agents], dtype=np.float64)
        self.returns += self.rewards
        self.t += 1


class LiveEpisode:
    """Lanes stepped in lock-step (module docstring)."""

    def __init__(self, engine: InferenceEngine, settings: EpisodeSettings) -> None:
        check_episode(settings)
        self.settings = settings
        self.lanes = [_Lane(engine, settings, method) for method in settings.methods]

    def header(self) -> dict[str, Any]:
        """What the page needs before the first frame."""
        s = self.settings
        lane = self.lanes[0]
        inferred = set(s.inferred)
        agents = [
            {
                "index": i,
                "name": name,
                "goal": goal,
                "role": "ego" if i == 0 else "partner",
                "inferred": i in inferred,
            }
            for i, (name, goal) in enumerate(zip(lane.agents, lane.goals, strict=True))
        ]
        return {
            "type": "episode",
            "settings": s.to_json(),
            "agents": agents,
            "action_meanings": list(env_runtime(s.env).info.action_meanings),
            "scene": get_drawing(s.env).scene(lane.env).to_json(),
        }

    def frames(self) -> Iterator[dict[str, Any]]:
        """Frame t = 0, 1, ... until every lane has sent its final frame, then a summary."""
        for t in range(self.settings.max_steps + 1):
            lanes = [lane.frame() for lane in self.lanes]
            yield {"type": "frame", "t": t, "lanes": lanes}
            if all(lane.ended for lane in self.lanes):
                break
            for lane in self.lanes:
                lane.advance()
        yield {"type": "end", "lanes": [_summary(lane) for lane in self.lanes]}


def _summary(lane: _Lane) -> dict[str, Any]:
    return {
        "method": lane.method,
        "length": lane.t,
        "returns": lane.returns.tolist(),
        "team_return": float(lane.returns.sum()),
    }


def parse_list(text: str | None) -> tuple[str, ...]:
    """ "a2, b3" -> ("a2", "b3"); None or "" -> ()."""
    return tuple(part.strip() for part in (text or "").split(",") if part.strip())


def parse_indices(text: str | None, field: str) -> tuple[int, ...]:
    """ "1,2" -> (1, 2); `InvalidRequest(field)` for anything but integers."""
    try:
        return tuple(int(part) for part in parse_list(text))
    except ValueError:
        raise InvalidRequest(
            field, f"expected comma-separated partner numbers, got {text!r}"
        ) from None
