"""What a user would serve instead of coexist: the same AAIL act on the same networks, written
on top of the model store with numpy, behind a plain FastAPI app or Ray Serve
(`benchmarks/alternatives_bench.py` measures them beside `coexist serve`).

Run: `.venv/bin/python benchmarks/alternative_servers.py fastapi PORT STORE_URL` or
`... ray PORT STORE_URL [MAX_ONGOING_REQUESTS]` (until SIGTERM or SIGINT).

| server    | what                                                                           |
|-----------|--------------------------------------------------------------------------------|
| `fastapi` | `plain_app` on uvicorn with coexist's settings: uvloop, httptools, one worker, |
|           | no access log                                                                  |
| `ray`     | `plain_app` as the FastAPI ingress of a one-replica Ray Serve deployment, on a |
|           | local Ray started here with one CPU (no dashboard); HTTP on the given port;     |
|           | Serve's defaults otherwise (its `max_ongoing_requests` unless given: beyond it  |
|           | the replica rejects a request and the proxy retries it after a back-off)        |

Both answer `GET /healthz` with `{"status": "ok"}` and `POST /v1/act` with
`{"probs": [...], "action": a}` for a body `{env, ego_goal, observation, partners: [{index,
goal}], method, temperature?, seed?}` (`method` "aail" only, the particle world only).

`NumpyAAIL` is the maths both share, what a user writes from the paper and the store's API
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

import os
import signal
import sys
import threading
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

    def probs(
        self,
        ego_goal: str,
        observation: list[float],
        partners: list[tuple[int, str]],
        temperature: float | None = None,
    ) -> np.ndarray:
        """The AAIL policy (A,) float64 for one observation; KeyError for a missing network,
        ValueError for an observation that is not whole particle blocks of >= 2 agents."""
        obs = np.asarray(observation, dtype=np.float32)
        if obs.ndim != 1 or obs.size % STATE_DIM or obs.size < 2 * STATE_DIM:
            raise ValueError(f"observation: expected 4 N values, N >= 2, got {obs.size}")
        blocks_N4 = obs.reshape(-1, STATE_DIM)
        ego_K4 = np.broadcast_to(blocks_N4[0], (len(blocks_N4) - 1, STATE_DIM))
        views_K8 = np.concatenate([ego_K4, blocks_N4[1:]], axis=1)  # view j: [ego, other j]
        task_layers, task_alpha = self.networks[f"{self.env}/task/{ego_goal}"]
        q_task = forward(task_layers, views_K8)
        q_task_A = (np.add.reduce(q_task, axis=0) / len(views_K8)).astype(np.float64)
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


def plain_app(url: str) -> Any:
    """The FastAPI app of both servers: `GET /healthz`, `POST /v1/act`."""
    from fastapi import FastAPI, HTTPException

    app = FastAPI()
    policy = NumpyAAIL(url)

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


def main() -> None:
    kind, port, url = sys.argv[1], int(sys.argv[2]), sys.argv[3]
    if kind == "ray":
        serve_ray(port, url, int(sys.argv[4]) if len(sys.argv) > 4 else None)
    else:
        serve_fastapi(port, url)


if __name__ == "__main__":
    main()
