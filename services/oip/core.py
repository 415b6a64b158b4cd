"""The v2 inference request as the engine's act, and its answer as v2 outputs.

Inputs (by name; every other name is refused):

| input            | datatype       | shape          | meaning                                             |
|------------------|----------------|----------------|-----------------------------------------------------|
| `observation`    | FP32 or FP64   | [D] or [B, D]  | the ego's observation(s), as `/v1/act`              |
| `ego_goal`       | BYTES          | [1]            | the ego's goal (or the request parameter `ego_goal`)|
| `partner_goals`  | BYTES          | [P]            | partner k's announced goal, k = 1..P (or the parameter `partner_goals`, comma-separated) |

Request parameters: `ego_goal`, `partner_goals`, `method`, `seed`, `temperature`,
`regret_bound`, `alias`. Outputs: `probabilities` FP64 [B, A], `action` INT64 [B] (sampled,
seeded by `seed`), `greedy_action` INT64 [B]. Bad input raises `InvalidRequest` naming the input
or parameter (`inputs[observation]`, `parameters.seed`): REST answers it 400, gRPC
INVALID_ARGUMENT.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from services.engine import (
    ActRequest,
    ActResult,
    EngineError,
    InferenceEngine,
    InvalidRequest,
    PartnerSpec,
)
from services.engine.environments import env_runtime

MODEL_VERSION = "1"
INPUT_NAMES = ("observation", "ego_goal", "partner_goals")
_PARAMETERS = {
    "ego_goal": str,
    "partner_goals": str,
    "method": str,
    "alias": str,
    "seed": int,
    "temperature": float,
    "regret_bound": float,
}


@dataclass(frozen=True)
class Tensor:
    """One input as either transport decoded it: its elements in a flat array or list."""

    name: str
    datatype: str
    shape: tuple[int, ...]
    data: Any  # a flat numpy array (numbers) or a list of str (BYTES)


def model_metadata(env: str) -> dict[str, Any]:
    """The model (environment) `env` as v2 metadata: its inputs and outputs (-1: any length)."""
    runtime = env_runtime(env)
    return {
        "name": env,
        "versions": [MODEL_VERSION],
        "platform": "coexist",
        "inputs": [
            {"name": "observation", "datatype": "FP32", "shape": [-1, -1]},
            {"name": "ego_goal", "datatype": "BYTES", "shape": [1]},
            {"name": "partner_goals", "datatype": "BYTES", "shape": [-1]},
        ],
        "outputs": [
            {"name": "probabilities", "datatype": "FP64", "shape": [-1, runtime.domain.n_actions]},
            {"name": "action", "datatype": "INT64", "shape": [-1]},
            {"name": "greedy_action", "datatype": "INT64", "shape": [-1]},
        ],
    }


def _parameters(parameters: Mapping[str, Any]) -> dict[str, Any]:
    out = {}
    for key, value in parameters.items():
        kind = _PARAMETERS.get(key)
        field = f"parameters.{key}"
        if kind is None:
            raise InvalidRequest(field, f"unknown parameter (known: {', '.join(_PARAMETERS)})")
        if isinstance(value, bool) or not isinstance(value, (str, int, float)):
            raise InvalidRequest(field, f"expected a {kind.__name__}, got {value!r}")
        try:
            out[key] = kind(value) if kind is not int or isinstance(value, int) else int(value)
        except (TypeError, ValueError):
            raise InvalidRequest(field, f"expected a {kind.__name__}, got {value!r}") from None
    return out


def _observations(tensor: Tensor) -> np.ndarray:
    field = f"inputs[{tensor.name}]"
    if tensor.datatype not in ("FP32", "FP64"):
        raise InvalidRequest(field, f"expected datatype FP32 or FP64, got {tensor.datatype}")
    if len(tensor.shape) not in (1, 2) or any(d < 1 for d in tensor.shape):
        raise InvalidRequest(field, f"expected shape [D] or [B, D], got {list(tensor.shape)}")
    data = np.asarray(tensor.data, dtype=np.float64)
    if data.size != int(np.prod(tensor.shape)):
        raise InvalidRequest(field, f"{data.size} elements do not fill shape {list(tensor.shape)}")
    return data.reshape(-1, tensor.shape[-1])


def _strings(tensor: Tensor) -> list[str]:
    if tensor.datatype != "BYTES":
        raise InvalidRequest(f"inputs[{tensor.name}]", f"expected BYTES, got {tensor.datatype}")
    return [str(s) for s in tensor.data]


def act_request(env: str, tensors: Sequence[Tensor], parameters: Mapping[str, Any]) -> ActRequest:
    """The engine's request for a v2 inference on model `env` (module docstring)."""
    env_runtime(env)  # unknown env: InvalidRequest naming `env`
    settings = _parameters(parameters)
    by_name: dict[str, Tensor] = {}
    for tensor in tensors:
        if tensor.name not in INPUT_NAMES:
            raise InvalidRequest(
                f"inputs[{tensor.name}]", f"unknown input (known: {', '.join(INPUT_NAMES)})"
            )
        by_name[tensor.name] = tensor
    if "observation" not in by_name:
        raise InvalidRequest("inputs[observation]", "missing: the ego's observation(s)")
    if "ego_goal" in by_name:
        goals = _strings(by_name["ego_goal"])
        if len(goals) != 1:
            raise InvalidRequest("inputs[ego_goal]", f"expected one goal, got {len(goals)}")
        settings["ego_goal"] = goals[0]
    if "ego_goal" not in settings:
        raise InvalidRequest("inputs[ego_goal]", "missing: an input or the parameter ego_goal")
    partner_goals = settings.pop("partner_goals", "")
    partners = [g.strip() for g in partner_goals.split(",") if g.strip()]
    if "partner_goals" in by_name:
        partners = _strings(by_name["partner_goals"])
    return ActRequest(
        env=env,
        ego_goal=settings.pop("ego_goal"),
        observations=_observations(by_name["observation"]),
        partners=tuple(PartnerSpec(k + 1, goal=g) for k, g in enumerate(partners)),
        **settings,
    )


def infer(engine: InferenceEngine, request: ActRequest) -> list[ActResult]:
    """The engine's answer; its errors about `observations[b]` blame the v2 input instead
    (`inputs[observation][b]`), the name the client sent."""
    try:
        return engine.act(request)
    except EngineError as err:
        if err.field is None or not err.field.startswith("observations"):
            raise
        raise err.renamed("inputs[observation]" + err.field.removeprefix("observations")) from None


def outputs(results: Sequence[ActResult]) -> list[tuple[str, str, list[int], np.ndarray]]:
    """(name, datatype, shape, flat data) of each output."""
    probs = np.asarray([r.probs for r in results], dtype=np.float64)
    return [
        ("probabilities", "FP64", list(probs.shape), probs.ravel()),
        ("action", "INT64", [len(results)], np.asarray([r.action for r in results], np.int64)),
        (
            "greedy_action",
            "INT64",
            [len(results)],
            np.asarray([r.greedy_action for r in results], np.int64),
        ),
    ]


def model_ready(engine: InferenceEngine, env: str) -> bool:
    """Whether `env` is a known environment and the server is ready."""
    try:
        env_runtime(env)
    except InvalidRequest:
        return False
    status = engine.status()
    return bool(status.store_reachable and status.models_loaded > 0)
