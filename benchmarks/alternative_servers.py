"""What a user would serve instead of coexist: the same AAIL act on the same networks, written
on top of the model store with numpy, behind a plain FastAPI app, Ray Serve or grpcio
(`benchmarks/alternatives_bench.py` measures them beside `coexist serve`; `benchmarks/capacity.py`
drives the plain app's sessions under Ray Serve).

Run: `.venv/bin/python benchmarks/alternative_servers.py fastapi PORT STORE_URL`,
`... ray PORT STORE_URL [MAX_ONGOING_REQUESTS]` or `... grpcio PORT STORE_URL` (until SIGTERM
or SIGINT).

| server    | what                                                                           |
|-----------|--------------------------------------------------------------------------------|
| `fastapi` | `plain_app` on uvicorn with coexist's settings: uvloop, httptools, one worker, |
|           | no access log                                                                  |
| `ray`     | `plain_app` as the FastAPI ingress of a one-replica Ray Serve deployment, on a |
|           | local Ray started here with one CPU (no dashboard); HTTP on the given port;     |
|           | Serve's defaults otherwise (its `max_ongoing_requests` unless given: beyond it  |
|           | the replica rejects a request and the proxy retries it after a back-off)        |
| `grpcio`  | a hand-written `coexist.v1.PolicyService/Act` (the project's proto) on grpcio's |
|           | sync server with coexist's thread pool (`floor_servers.GRPC_THREADS`), the act  |
|           | in numpy (`NumpyAAIL`), plus the standard health servicer                      |

The HTTP servers answer `GET /healthz` with `{"status": "ok"}` and `POST /v1/act` with
`{"probs": [...], "action": a}` for a body `{env, ego_goal, observation, partners: [{index,
goal}], method, temperature?, seed?}` (`method` "aail" only, the particle world only). The
grpcio server answers `Act` with `probs`, `action`, `greedy_action` and `method` (no
diagnostics, no model list: what a user needs, fewer bytes than coexist's answer).

Sessions (HTTP servers; `NumpySessions`): `POST /v1/sessions` with `{env, ego_goal, partners:
[{index, infer: true}], method: "aail", seed?}` answers 201 `{"session_id"}`, and `POST
/v1/sessions/{id}/steps` with `{observation, observed?: [{index, action}]}` answers `{"probs",
"action", "step", "beliefs": [{"index", "top": [{"goal", "prob"}]}]}`. Each partner's belief
over the particle world's goals is updated from its observed action as coexist's default belief
is (the Boltzmann likelihood of every goal's task network on the partner's view [partner, ego]
of the previous observation at twice that network's training α, forgetting 0.95 toward the
uniform prior, floor 1e-3), then the act mixes each partner's impact Q over every goal's impact
network by its belief (the expected impact Q, §3.2) and blends it by AAIL; step t samples with
seed + t. The sessions live in the process's memory (one replica). tests/benchmarks/
test_alternative_servers.py holds the answers to a coexist `Session`'s within 1e-5.

`NumpyAAIL` is the maths all share, what a user writes from the paper and the store's API
without coexist's engine or compiled kernels: each network's production version read once
from the store (`model_store.open_store`, weights from safetensors bytes with
`safetensors.numpy`, never pickle), then per request in numpy: the ego's N - 1 pair views
[ego, other_j] of the observation (`envs.particle.domain.ParticleDomain.task_views`), the task
network on every view and its Q averaged over them, partner p's impact network on its view,
and AAIL (eqs. 8-10, Q-vectors standardised before eq. 8 as `policy.blend` does for the
particle world), then a Boltzmann policy and an action sampled by inverse CDF (`seed`: a
generator seeded with it, as coexist does; else one generator of the server's).
tests/benchmarks/test_alternative_servers.py holds its probabilities to coexist's engine within 1e-5.
"""

import math
import os
import signal
import sys
import threading
import uuid
from collections.abc import Sequence
from concurrent import futures
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel, Field

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

DEFAULT_ALPHA = 0.02  # coexist's temperature when a network's lineage has none
FLAT_STD_RTOL = 1e-12  # a Q-vector whose std is below this fraction of max |Q| is flat
ALIAS = "production"
STATE_DIM = 4  # a particle's block: x, y, vx, vy
# coexist's default belief (`policy.belief.BeliefConfig`, `services.engine.goal_inference`)
LIKELIHOOD_TEMPERING = 4.0  # the likelihood's α over each task network's training α
LIKELIHOOD_NOISE = 0.3  # η: the likelihood mixes the tempered policy with uniform actions
FORGETTING = 0.95  # λ: each update pulls the belief back toward the prior by 1 - λ
FLOOR = 1e-3  # ε: every goal keeps probability >= ε
TOP_GOALS = 3  # goals listed per partner in a step's answer

Layers = list[tuple[np.ndarray, np.ndarray]]


# no `from __future__ import annotations` in this module: FastAPI reads the routes' annotations
# as objects, also where Ray has pickled the routes by value (their globals are not all there)
class Partner(BaseModel):
    index: int = Field(ge=1)
    goal: str


class ActBody(BaseModel):
    env: str
    ego_goal: str
    observation: list[float]
    partners: list[Partner] = []
    method: str = "aail"
    temperature: float | None = Field(default=None, gt=0)
    seed: int | None = None


class SessionPartnerIn(BaseModel):
    index: int = Field(ge=1)
    infer: bool = True


class SessionBody(BaseModel):
    env: str
    ego_goal: str
    partners: list[SessionPartnerIn] = []
    method: str = "aail"
    seed: int | None = None


class ObservedIn(BaseModel):
    index: int
    action: int = Field(ge=0)


class StepBody(BaseModel):
    observation: list[float]
    observed: list[ObservedIn] = []


def load_networks(url: str, env: str = "particle") -> dict[str, tuple[Layers, float]]:
    """Every model of `env` with a production version: name -> ([(W (in, out), b (out,))],
    training α), float32."""
    from safetensors.numpy import load

    from model_store import open_store

    networks: dict[str, tuple[Layers, float]] = {}
    with open_store(url) as store:
        token = None
        while True:
            page = store.list_models(env=env, page_token=token)
            for model in page.items:
                if ALIAS not in model.aliases:
                    continue
                version = store.resolve(f"{model.name}@{ALIAS}")
                tensors = load(store.load_weights(version.name, version.version))
                layers = [
                    (
                        np.ascontiguousarray(tensors[f"layers.{k}.weight"].astype(np.float32).T),
                        tensors[f"layers.{k}.bias"].astype(np.float32),
                    )
                    for k in range(len(version.spec["hidden"]) + 1)
                ]
                alpha = version.lineage.config.get("alpha", DEFAULT_ALPHA)
                networks[model.name] = (layers, float(alpha))
            token = page.next_page_token
            if not token:
                break
    return networks


def forward(layers: Layers, x: np.ndarray) -> np.ndarray:
    """The MLP: ReLU hidden layers, a linear output; float32 rows in, float32 Q-values out."""
    h = x
    for weight, bias in layers[:-1]:
        h = h @ weight
        h += bias
        np.maximum(h, 0.0, out=h)
    weight, bias = layers[-1]
    return h @ weight + bias


def stack(networks: Sequence[Layers]) -> Layers:
    """Networks of one architecture as one stack: [(W (G, in, out), b (G, 1, out))], so that
    `forward(stacked, x)` with x (rows, in) gives every network's Q-values, (G, rows, out)."""
    return [
        (
            np.stack([layers[k][0] for layers in networks]),
            np.stack([layers[k][1] for layers in networks])[:, None, :],
        )
        for k in range(len(networks[0]))
    ]


def boltzmann(q: np.ndarray, alpha: float) -> np.ndarray:
    """π(a) ∝ exp(Q(a) / α) over the last axis (eq. 2)."""
    e = np.exp((q - q.max(axis=-1, keepdims=True)) / alpha)
    return e / e.sum(axis=-1, keepdims=True)


def standardise(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """z-scores over the last axis and the std; a flat vector gets z = 0 and std 0."""
    magnitude = np.abs(q).max(axis=-1, keepdims=True)
    unit = q / np.where(magnitude > 0, magnitude, 1.0)
    std = unit.std(axis=-1, keepdims=True)
    flat = std <= FLAT_STD_RTOL
    z = np.where(flat, 0.0, (unit - unit.mean(axis=-1, keepdims=True)) / np.where(flat, 1.0, std))
    return z, np.where(flat, 0.0, std * magnitude)[..., 0]


def _p_log2_ratio(p: np.ndarray, m: np.ndarray) -> np.ndarray:
    positive = p > 0
    return np.where(positive, p * np.log2(np.where(positive, p / m, 1.0)), 0.0).sum(axis=-1)


def aail(q_task_A: np.ndarray, q_impact_PA: np.ndarray, alpha: float) -> np.ndarray:
    """AAIL's policy (A,) float64 from the task Q (A,) and one impact Q per partner (P, A)."""
    n_actions = q_task_A.shape[-1]
    pi_task = boltzmann(q_task_A, alpha)
    if len(q_impact_PA) == 0:
        return boltzmann(q_task_A - q_task_A.mean(), alpha)
    # eq. 9: w_t = 1 - |A|^H(π_t) / |A|, H normalised by log |A|
    positive = pi_task > 0
    entropy = -np.where(positive, pi_task * np.log(np.where(positive, pi_task, 1.0)), 0.0).sum()
    entropy = min(max(entropy / np.log(n_actions), 0.0), 1.0)
    w_task = 1.0 - n_actions**entropy / n_actions
    # eq. 10: w_i = the Jensen-Shannon distance (base 2) between π_t and π_i, normalised
    pi_impact = boltzmann(q_impact_PA, alpha)
    mixture = 0.5 * (pi_task + pi_impact)
    divergence = 0.5 * _p_log2_ratio(pi_task, mixture) + 0.5 * _p_log2_ratio(pi_impact, mixture)
    w_partner = np.sqrt(np.clip(divergence, 0.0, 1.0))
    total = w_partner.sum()
    w_hat = w_partner / total if total > 0 else np.full(len(w_partner), 1.0 / len(w_partner))
    # eq. 8 on the standardised Q-vectors, the same weights on their scales
    z_task, s_task = standardise(q_task_A)
    z_impact, s_impact = standardise(q_impact_PA)
    z = w_task * z_task + (1.0 - w_task) * (w_hat @ z_impact)
    s = w_task * s_task + (1.0 - w_task) * float(w_hat @ s_impact)
    return boltzmann(s * z, alpha)


class NumpyAAIL:
    """The particle world's AAIL act on the networks of the store at `url` (module docstring)."""

    def __init__(self, url: str, env: str = "particle") -> None:
        self.env = env
        self.networks = load_networks(url, env)
        self._rng = np.random.default_rng()
        self._lock = threading.Lock()  # a Generator is not thread-safe

    def views(self, observation: Sequence[float]) -> np.ndarray:
        """The ego's pair views [ego, other_j], (N - 1, 8) float32; ValueError for an
        observation that is not whole particle blocks of >= 2 agents."""
        obs = np.asarray(observation, dtype=np.float32)
        if obs.ndim != 1 or obs.size % STATE_DIM or obs.size < 2 * STATE_DIM:
            raise ValueError(f"observation: expected 4 N values, N >= 2, got {obs.size}")
        blocks_N4 = obs.reshape(-1, STATE_DIM)
        ego_K4 = np.broadcast_to(blocks_N4[0], (len(blocks_N4) - 1, STATE_DIM))
        return np.concatenate([ego_K4, blocks_N4[1:]], axis=1)  # view j: [ego, other j]

    def task_q(self, ego_goal: str, views_K8: np.ndarray) -> tuple[np.ndarray, float]:
        """The ego's task Q (A,) float64, averaged over its views, and the network's α;
        KeyError for a missing network."""
        task_layers, task_alpha = self.networks[f"{self.env}/task/{ego_goal}"]
        q_task = forward(task_layers, views_K8)
        return (np.add.reduce(q_task, axis=0) / len(views_K8)).astype(np.float64), task_alpha

    def probs(
        self,
        ego_goal: str,
        observation: Sequence[float],
        partners: list[tuple[int, str]],
        temperature: float | None = None,
    ) -> np.ndarray:
        """The AAIL policy (A,) float64 for one observation; KeyError for a missing network,
        ValueError for an observation that is not whole particle blocks of >= 2 agents,
        IndexError for a partner it does not hold."""
        views_K8 = self.views(observation)
        q_task_A, task_alpha = self.task_q(ego_goal, views_K8)
        q_impact = [
            forward(self.networks[f"{self.env}/impact/{goal}"][0], views_K8[index - 1])
            for index, goal in partners
        ]
        q_impact_PA = np.array(q_impact, dtype=np.float64).reshape(len(partners), -1)
        return aail(q_task_A, q_impact_PA, temperature or task_alpha)

    def sample(self, probs: np.ndarray, seed: int | None = None) -> int:
        """An action by inverse CDF from one uniform: a generator seeded with `seed`, else
        the server's."""
        if seed is None:
            with self._lock:
                u = self._rng.random()
        else:
            u = np.random.default_rng(seed).random()
        cdf = np.cumsum(probs)
        return min(int(np.count_nonzero(cdf <= u * cdf[-1])), len(probs) - 1)


def _log_normalised(x: np.ndarray) -> np.ndarray:
    top = x.max(axis=-1, keepdims=True)
    return x - (top + np.log(np.exp(x - top).sum(axis=-1, keepdims=True)))


def _floored(log_b: np.ndarray, n_goals: int) -> np.ndarray:
    """log((1 - G ε) b + ε): every goal keeps probability >= ε."""
    return np.logaddexp(math.log1p(-n_goals * FLOOR) + log_b, math.log(FLOOR))


@dataclass
class _Session:
    ego_goal: str
    partners: tuple[int, ...]  # the inferred partners' indices
    seed: int | None
    log_belief_PG: np.ndarray  # float64
    previous: np.ndarray | None = None  # the last step's observation, float32 (D,)
    step: int = 0


class NumpySessions:
    """Sessions with inferred partners over `policy`'s networks (module docstring): every goal
    of `goals` needs its task and impact network (KeyError naming the first missing)."""

    def __init__(self, policy: NumpyAAIL, goals: Sequence[str]) -> None:
        self.policy, self.goals = policy, tuple(goals)
        nets, env = policy.networks, policy.env
        self.task_G = stack([nets[f"{env}/task/{g}"][0] for g in self.goals])
        self.impact_G = stack([nets[f"{env}/impact/{g}"][0] for g in self.goals])
        alphas = [nets[f"{env}/task/{g}"][1] for g in self.goals]
        self.likelihood_alpha_G11 = LIKELIHOOD_TEMPERING * np.array(alphas)[:, None, None]
        n_goals = len(self.goals)
        # the uniform prior with the floor (uniform still); the forgetting term pulls toward it
        self.log_prior_G = _floored(np.full(n_goals, -math.log(n_goals)), n_goals)
        self.pull_G = (1.0 - FORGETTING) * self.log_prior_G
        self.sessions: dict[str, _Session] = {}

    def create(self, ego_goal: str, partners: Sequence[int], seed: int | None = None) -> str:
        """A new session's id; KeyError for an ego goal without a task network, ValueError
        for a partner index given twice."""
        if f"{self.policy.env}/task/{ego_goal}" not in self.policy.networks:
            raise KeyError(f"{self.policy.env}/task/{ego_goal}")
        if len(set(partners)) != len(partners):
            raise ValueError("partners: an index given twice")
        session_id = uuid.uuid4().hex
        log_belief_PG = np.tile(self.log_prior_G, (len(partners), 1))
        self.sessions[session_id] = _Session(ego_goal, tuple(partners), seed, log_belief_PG)
        return session_id

    def step(
        self, session_id: str, observation: Sequence[float], observed: Sequence[tuple[int, int]]
    ) -> dict[str, object]:
        """Update the beliefs with the partners' actions `observed` [(index, action)] since the
        previous step, then act on `observation`; LookupError for an unknown session,
        ValueError for a bad observation or entry (the session is left unchanged)."""
        if session_id not in self.sessions:
            raise LookupError(f"no session {session_id!r}")
        session = self.sessions[session_id]
        views_K8 = self.policy.views(observation)
        if max(session.partners, default=0) > len(views_K8):
            raise ValueError(f"observation: holds {len(views_K8) + 1} agents, too few")
        log_belief_PG = session.log_belief_PG
        if observed:
            log_belief_PG = self._updated(session, observed)
        probs_PG = np.exp(log_belief_PG)
        probs_PG /= probs_PG.sum(axis=1, keepdims=True)
        q_task_A, alpha = self.policy.task_q(session.ego_goal, views_K8)
        # each partner's impact Q, mixed over every goal's network by its belief (§3.2)
        q_GPA = forward(self.impact_G, views_K8[[i - 1 for i in session.partners]])
        q_impact_PA = np.einsum("pg,gpa->pa", probs_PG, q_GPA.astype(np.float64))
        probs = aail(q_task_A, q_impact_PA, alpha)
        t = session.step
        action = self.policy.sample(probs, None if session.seed is None else session.seed + t)
        session.log_belief_PG = log_belief_PG
        session.previous = np.asarray(observation, dtype=np.float32)
        session.step = t + 1
        beliefs = []
        for index, row in zip(session.partners, log_belief_PG, strict=True):
            top = np.argsort(-row, kind="stable")[:TOP_GOALS]
            beliefs.append(
                {
                    "index": index,
                    "top": [{"goal": self.goals[g], "prob": float(np.exp(row[g]))} for g in top],
                }
            )
        return {"probs": probs.tolist(), "action": action, "step": t, "beliefs": beliefs}

    def _updated(self, session: _Session, observed: Sequence[tuple[int, int]]) -> np.ndarray:
        """The beliefs after one observed action per listed partner (a new array): the
        Boltzmann likelihood of every goal's task network on the partner's view [partner,
        ego] of the previous observation, mixed with uniform action noise, forgetting toward
        the prior, then the floor."""
        if session.previous is None:
            raise ValueError("observed: none at step 0 (no previous observation)")
        indices = [index for index, _ in observed]
        if len(set(indices)) != len(indices) or not set(indices) <= set(session.partners):
            raise ValueError(f"observed: each index once, among {list(session.partners)}")
        actions_E = np.array([action for _, action in observed])
        q_GEA = self._likelihood_q(session.previous, indices)
        if actions_E.min() < 0 or actions_E.max() >= q_GEA.shape[2]:
            raise ValueError(f"observed: actions in 0..{q_GEA.shape[2] - 1}")
        z = q_GEA.astype(np.float64)
        z -= z.max(axis=2, keepdims=True)
        z /= self.likelihood_alpha_G11
        log_norm_GE = np.log(np.exp(z).sum(axis=2))
        rows = np.arange(len(indices))
        policy_EG = np.exp(z[:, rows, actions_E] - log_norm_GE).T
        n_actions = q_GEA.shape[2]
        log_lik_EG = np.log((1.0 - LIKELIHOOD_NOISE) * policy_EG + LIKELIHOOD_NOISE / n_actions)
        which = [session.partners.index(i) for i in indices]
        log_belief_PG = session.log_belief_PG.copy()
        x = FORGETTING * log_belief_PG[which] + log_lik_EG + self.pull_G
        log_belief_PG[which] = _floored(_log_normalised(x), len(self.goals))
        return log_belief_PG

    def _likelihood_q(self, previous: np.ndarray, indices: Sequence[int]) -> np.ndarray:
        """Every goal's task Q on each partner's view [partner, ego], (G, E, A) float32."""
        blocks_N4 = previous.reshape(-1, STATE_DIM)
        if max(indices) >= len(blocks_N4):
            raise ValueError("observed: a partner the previous observation does not hold")
        partner_E4 = blocks_N4[list(indices)]
        ego_E4 = np.broadcast_to(blocks_N4[0], partner_E4.shape)
        return forward(self.task_G, np.concatenate([partner_E4, ego_E4], axis=1))


def plain_app(url: str) -> Any:
    """The FastAPI app of both HTTP servers: `GET /healthz`, `POST /v1/act`, `POST
    /v1/sessions` and `POST /v1/sessions/{id}/steps`."""
    from fastapi import FastAPI, HTTPException

    from envs.particle.goals import GOAL_IDS

    app = FastAPI()
    policy = NumpyAAIL(url)
    # stacked on the first session: a store of a few networks still serves /v1/act
    sessions: list[NumpySessions] = []

    @app.get("/healthz")
    async def healthz() -> dict[str, str]:
        return {"status": "ok"}

    # `async def` as coexist's route: run on the event loop, no thread-pool hop (a forward of
    # a few rows is shorter than the hop, and one CPU runs either way)
    @app.post("/v1/act")
    async def act(body: ActBody) -> dict[str, Any]:
        if body.env != policy.env or body.method != "aail":
            raise HTTPException(422, f"serves env {policy.env!r}, method 'aail' only")
        partners = [(p.index, p.goal) for p in body.partners]
        try:
            probs = policy.probs(body.ego_goal, body.observation, partners, body.temperature)
        except KeyError as exc:
            raise HTTPException(404, f"no production network {exc}") from None
        except (ValueError, IndexError) as exc:
            raise HTTPException(422, str(exc)) from None
        return {"probs": probs.tolist(), "action": policy.sample(probs, body.seed)}

    @app.post("/v1/sessions", status_code=201)
    async def create_session(body: SessionBody) -> dict[str, str]:
        if body.env != policy.env or body.method != "aail":
            raise HTTPException(422, f"serves env {policy.env!r}, method 'aail' only")
        if not all(p.infer for p in body.partners):
            raise HTTPException(422, "partners: inferred partners only (infer: true)")
        try:
            if not sessions:
                sessions.append(NumpySessions(policy, GOAL_IDS))
            session_id = sessions[0].create(
                body.ego_goal, [p.index for p in body.partners], body.seed
            )
        except KeyError as exc:
            raise HTTPException(404, f"no production network {exc}") from None
        except ValueError as exc:
            raise HTTPException(422, str(exc)) from None
        return {"session_id": session_id}

    @app.post("/v1/sessions/{session_id}/steps")
    async def step_session(session_id: str, body: StepBody) -> dict[str, Any]:
        observed = [(o.index, o.action) for o in body.observed]
        try:
            if not sessions:
                raise LookupError(f"no session {session_id!r}")
            return sessions[0].step(session_id, body.observation, observed)
        except LookupError as exc:
            raise HTTPException(404, str(exc)) from None
        except ValueError as exc:
            raise HTTPException(422, str(exc)) from None

    return app


def serve_fastapi(port: int, url: str) -> None:
    from floor_servers import run_uvicorn

    run_uvicorn(plain_app(url), port)


def serve_ray(port: int, url: str, max_ongoing_requests: int | None = None) -> None:
    """`plain_app` behind Ray Serve: one replica on a local one-CPU Ray, until SIGTERM/SIGINT,
    then Serve and Ray shut down (Ray's actors run in process groups of their own: signal this
    process alone, not its group, or the raylet dies first and Serve's shutdown hangs)."""
    import ray
    from ray import serve

    # Ray's workers inherit the environment: the replica imports this checkout's packages
    os.environ["PYTHONPATH"] = os.pathsep.join(
        p for p in (str(ROOT), os.environ.get("PYTHONPATH", "")) if p
    )
    ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False)
    stopped = threading.Event()  # after ray.init, which installs a SIGTERM handler of its own
    signal.signal(signal.SIGTERM, lambda *_: stopped.set())
    signal.signal(signal.SIGINT, lambda *_: stopped.set())
    try:

        def build_app() -> Any:  # evaluated on the replica: the weights are read there
            return plain_app(url)

        ingress = serve.ingress(build_app)()
        options: dict[str, Any] = {"num_replicas": 1}
        if max_ongoing_requests is not None:
            options["max_ongoing_requests"] = max_ongoing_requests
        deployment = serve.deployment(**options)(ingress)
        serve.start(http_options={"host": "127.0.0.1", "port": port})
        serve.run(deployment.bind(), name="plain", route_prefix="/", blocking=False)
        while not stopped.wait(0.5):
            pass
    finally:
        serve.shutdown()
        ray.shutdown()


def grpcio_server(url: str, port: int) -> tuple[Any, int]:
    """The hand-written grpcio server (not started) and the port it is bound to (`port` 0:
    the OS picks): `coexist.v1.PolicyService/Act` on `NumpyAAIL`, the health servicer."""
    import grpc
    from floor_servers import GRPC_THREADS
    from grpc_health.v1 import health, health_pb2, health_pb2_grpc

    from services.grpc_api.gen.coexist.v1 import policy_pb2 as pb
    from services.grpc_api.gen.coexist.v1 import policy_pb2_grpc as pb_grpc

    policy = NumpyAAIL(url)

    class NumpyPolicyServicer(pb_grpc.PolicyServiceServicer):
        """`Act` only; the other methods answer UNIMPLEMENTED, the generated default."""

        def Act(self, request: Any, context: Any) -> Any:  # the proto's method name
            if request.env != policy.env or request.method != "aail":
                context.abort(
                    grpc.StatusCode.INVALID_ARGUMENT,
                    f"serves env {policy.env!r}, method 'aail' only",
                )
            partners = [(p.index, p.goal) for p in request.partners]
            temperature = request.temperature if request.HasField("temperature") else None
            try:
                probs = policy.probs(request.ego_goal, request.observation, partners, temperature)
            except KeyError as exc:
                context.abort(grpc.StatusCode.NOT_FOUND, f"no production network {exc}")
            except (ValueError, IndexError) as exc:
                context.abort(grpc.StatusCode.INVALID_ARGUMENT, str(exc))
            seed = request.seed if request.HasField("seed") else None
            return pb.ActResponse(
                probs=probs.tolist(),
                action=policy.sample(probs, seed),
                greedy_action=int(np.argmax(probs)),
                method="aail",
            )

    server = grpc.server(futures.ThreadPoolExecutor(max_workers=GRPC_THREADS))
    pb_grpc.add_PolicyServiceServicer_to_server(NumpyPolicyServicer(), server)
    checks = health.HealthServicer()
    checks.set("", health_pb2.HealthCheckResponse.SERVING)
    health_pb2_grpc.add_HealthServicer_to_server(checks, server)
    return server, server.add_insecure_port(f"127.0.0.1:{port}")


def serve_grpcio(port: int, url: str) -> None:
    server, _ = grpcio_server(url, port)
    stopped = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stopped.set())
    signal.signal(signal.SIGINT, lambda *_: stopped.set())
    server.start()
    stopped.wait()
    server.stop(grace=1.0).wait()


def main() -> None:
    kind, port, url = sys.argv[1], int(sys.argv[2]), sys.argv[3]
    if kind == "ray":
        serve_ray(port, url, int(sys.argv[4]) if len(sys.argv) > 4 else None)
    elif kind == "grpcio":
        serve_grpcio(port, url)
    else:
        serve_fastapi(port, url)


if __name__ == "__main__":
    main()
