"""The v2 inference request as the engine's act, and its answer as v2 outputs; the facts behind
the model metadata, configuration, repository index and statistics.

Inputs (by name; every other name is refused):

| input            | datatype       | shape          | meaning                                             |
|------------------|----------------|----------------|-----------------------------------------------------|
| `observation`    | FP32 or FP64   | [D] or [B, D]  | the ego's observation(s), as `/v1/act`              |
| `ego_goal`       | BYTES          | [1]            | the ego's goal (or the request parameter `ego_goal`)|
| `partner_goals`  | BYTES          | [P]            | partner k's announced goal, k = 1..P (or the parameter `partner_goals`, comma-separated) |

Outputs: `probabilities` FP64 [B, A], `action` INT64 [B] (sampled, seeded by `seed`),
`greedy_action` INT64 [B]; all three unless the request names some (`outputs`).

Request parameters: coexist's `ego_goal`, `partner_goals`, `method`, `seed`, `temperature`,
`regret_bound`, `alias`; the protocol's `binary_data_output` (REST: every output as binary data);
`priority` and `timeout` are accepted and have no effect (one request is one act, never queued
behind a scheduler); the sequence parameters are refused (the networks keep no state between
requests: `/v1/sessions` keeps a belief).

A model is an environment; its one version is "1" (what the registry's aliases serve now, the
`alias` parameter choosing which). An unknown model or version raises `ModelNotFound` (REST
404, gRPC NOT_FOUND); bad input raises `InvalidRequest` naming the input or parameter
(`inputs[observation]`, `parameters.seed`: REST 400, gRPC INVALID_ARGUMENT).
"""

from __future__ import annotations

import struct
import threading
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from envs.registry import known_envs
from model_store.errors import ModelStoreError, brief
from services.engine import (
    ActRequest,
    ActResult,
    EngineError,
    InferenceEngine,
    InvalidRequest,
    ModelNotFound,
    PartnerSpec,
)
from services.engine.environments import EnvRuntime, env_runtime

MODEL_VERSION = "1"
PLATFORM = "coexist"
# What the server metadata announces: Triton's names of the protocol extensions served here.
EXTENSIONS = (
    "binary_tensor_data",
    "model_configuration",
    "model_repository",
    "statistics",
    "parameters",
)
INPUT_NAMES = ("observation", "ego_goal", "partner_goals")
OUTPUT_NAMES = ("probabilities", "action", "greedy_action")
_PARAMETERS = {
    "ego_goal": str,
    "partner_goals": str,
    "method": str,
    "alias": str,
    "seed": int,
    "temperature": float,
    "regret_bound": float,
}
_KIND = {str: "a string", int: "an integer", float: "a number"}
_IGNORED = ("priority", "timeout")  # accepted, no effect (module docstring)
_REFUSED = {
    "sequence_id": "sequences are not served: every request is one stateless act "
    "(/v1/sessions keeps a belief over partners' goals)",
    "sequence_start": "sequences are not served",
    "sequence_end": "sequences are not served",
}
_NUMPY = {"FP32": "<f4", "FP64": "<f8", "INT32": "<i4", "INT64": "<i8"}


@dataclass(frozen=True)
class Tensor:
    """One input as either transport decoded it: its elements in a flat array or list."""

    name: str
    datatype: str
    shape: tuple[int, ...]
    data: Any  # a flat numpy array (numbers) or a list of str (BYTES)


@dataclass(frozen=True)
class Inference:
    """A v2 inference request, decoded: the act, the outputs to answer, and how (REST)."""

    act: ActRequest
    outputs: tuple[tuple[str, bool], ...]  # (name, as binary data), in answer order


def check_model(env: str, version: str | None = None) -> EnvRuntime:
    """The environment served as model `env`, version `version` (None or "": the one there is);
    `ModelNotFound` for any other name or version."""
    if env not in known_envs():
        raise ModelNotFound(
            env,
            MODEL_VERSION,
            field="model_name",
            message=f"unknown model {brief(env)} (known: {', '.join(known_envs())})",
        )
    if version not in (None, "", MODEL_VERSION):
        raise ModelNotFound(
            env,
            version,
            field="model_version",
            message=f"model {env} has no version {brief(version)} (its one version is "
            f"{MODEL_VERSION}: what the registry's aliases serve)",
        )
    return env_runtime(env)


def _tensor_metadata(name: str, datatype: str, shape: list[int]) -> dict[str, Any]:
    return {"name": name, "datatype": datatype, "shape": shape}


def model_metadata(env: str, version: str | None = None) -> dict[str, Any]:
    """The model (environment) `env` as v2 metadata: full shapes, -1 for the batch and for the
    observation's length (it grows with the partners) and the number of partners."""
    runtime = check_model(env, version)
    return {
        "name": env,
        "versions": [MODEL_VERSION],
        "platform": PLATFORM,
        "inputs": [
            _tensor_metadata("observation", "FP32", [-1, -1]),
            _tensor_metadata("ego_goal", "BYTES", [1]),
            _tensor_metadata("partner_goals", "BYTES", [-1]),
        ],
        "outputs": [
            _tensor_metadata("probabilities", "FP64", [-1, runtime.domain.n_actions]),
            _tensor_metadata("action", "INT64", [-1]),
            _tensor_metadata("greedy_action", "INT64", [-1]),
        ],
    }


def model_config(env: str, version: str | None = None, *, max_batch: int) -> dict[str, Any]:
    """The model's configuration in Triton's terms (its model configuration extension), as JSON.

    `max_batch_size` is 0: the dims are full shapes, the batch first (-1) where there is one,
    since the goals are one per request, not one per row. `parameters` carries what a client
    needs to fill the inputs and read the outputs: the goal names, the action meanings, the
    observation length for each agent count, and the largest batch this server takes."""
    runtime = check_model(env, version)
    info = runtime.info
    meta = model_metadata(env, version)

    def tensors(items: list[dict[str, Any]]) -> list[dict[str, Any]]:
        return [
            {"name": t["name"], "data_type": _CONFIG_TYPES[t["datatype"]], "dims": t["shape"]}
            for t in items
        ]

    dims = ",".join(f"{n}:{d}" for n, d in sorted(info.obs_dims.items()))
    return {
        "name": env,
        "platform": PLATFORM,
        "backend": PLATFORM,
        "version_policy": {"specific": {"versions": [int(MODEL_VERSION)]}},
        "max_batch_size": 0,
        "input": tensors(meta["inputs"]),
        "output": tensors(meta["outputs"]),
        "parameters": {
            "goals": {"string_value": ",".join(info.goals)},
            "action_meanings": {"string_value": ",".join(info.action_meanings)},
            "observation_dims": {"string_value": dims},  # agent count:length
            "max_batch": {"string_value": str(max_batch)},
        },
    }


_CONFIG_TYPES = {
    "FP32": "TYPE_FP32",
    "FP64": "TYPE_FP64",
    "INT64": "TYPE_INT64",
    "BYTES": "TYPE_STRING",
}


def model_state(engine: InferenceEngine, env: str) -> tuple[bool, str]:
    """(ready, reason) for model `env`: the store answers and holds networks of this env."""
    check_model(env)
    status = engine.status()
    if not status.store_reachable:
        return False, "the model store is unreachable"
    try:
        page = engine.store.list_models(env=env, page_size=1)
    except ModelStoreError as err:
        return False, f"the model store: {err}"
    if not page.items:
        return False, f"no networks of {env} in the registry"
    return True, ""


def repository_index(engine: InferenceEngine, ready_only: bool = False) -> list[dict[str, str]]:
    """Every model (environment) with its version and state, as Triton's repository index."""
    index = []
    for env in known_envs():
        ready, reason = model_state(engine, env)
        if ready_only and not ready:
            continue
        state = "READY" if ready else "UNAVAILABLE"
        index.append({"name": env, "version": MODEL_VERSION, "state": state, "reason": reason})
    return index


def split_parameters(parameters: Mapping[str, Any]) -> tuple[dict[str, Any], bool]:
    """(coexist's act settings, binary_data_output) from the request parameters."""
    settings = {}
    binary = False
    for key, value in parameters.items():
        field_name = f"parameters.{key}"
        if key == "binary_data_output":
            if not isinstance(value, bool):
                raise InvalidRequest(field_name, f"expected true or false, got {brief(value)}")
            binary = value
            continue
        if key in _IGNORED:
            if isinstance(value, bool) or not isinstance(value, int):
                raise InvalidRequest(field_name, f"expected an integer, got {brief(value)}")
            continue
        if key in _REFUSED:
            raise InvalidRequest(field_name, _REFUSED[key])
        kind = _PARAMETERS.get(key)
        if kind is None:
            known = ", ".join([*_PARAMETERS, "binary_data_output", *_IGNORED])
            raise InvalidRequest(field_name, f"unknown parameter (known: {known})")
        if (
            isinstance(value, bool)
            or not isinstance(value, (str, int, float))
            or (kind is int and isinstance(value, float) and not value.is_integer())
        ):
            raise InvalidRequest(field_name, f"expected {_KIND[kind]}, got {brief(value)}")
        try:
            settings[key] = kind(value)
        except (TypeError, ValueError, OverflowError):
            raise InvalidRequest(
                field_name, f"expected {_KIND[kind]}, got {brief(value)}"
            ) from None
    return settings, binary


def requested_outputs(
    requested: Sequence[tuple[str, Mapping[str, Any]]] | None, binary_default: bool
) -> tuple[tuple[str, bool], ...]:
    """(name, as binary data) of each output to answer: the ones named, else all three.

    An output's `binary_data` parameter overrides the request's `binary_data_output`; Triton's
    classification extension (`classification`) is not served."""
    if not requested:
        return tuple((name, binary_default) for name in OUTPUT_NAMES)
    chosen: dict[str, bool] = {}
    for name, parameters in requested:
        where = f"outputs[{name}]"
        if name not in OUTPUT_NAMES:
            raise InvalidRequest(where, f"unknown output (known: {', '.join(OUTPUT_NAMES)})")
        binary = binary_default
        for key, value in parameters.items():
            if key == "binary_data" and isinstance(value, bool):
                binary = value
            elif key == "binary_data":
                raise InvalidRequest(f"{where}.parameters.binary_data", "expected true or false")
            elif key == "classification":
                raise InvalidRequest(
                    f"{where}.parameters.classification",
                    "the classification extension is not served: read `probabilities` "
                    "(the config's parameter action_meanings names each action)",
                )
            else:
                raise InvalidRequest(f"{where}.parameters.{key}", "unknown output parameter")
        chosen[name] = binary
    return tuple(chosen.items())


def decode_raw(name: str, datatype: str, raw: bytes) -> Any:
    """A tensor's elements from the protocol's binary form: little-endian numbers, or for BYTES
    each element after its 4-byte little-endian length."""
    field_name = f"inputs[{name}]"
    if datatype == "BYTES":
        out, offset = [], 0
        while offset < len(raw):
            if offset + 4 > len(raw):
                raise InvalidRequest(field_name, "BYTES binary data cut short")
            (size,) = struct.unpack_from("<I", raw, offset)
            if offset + 4 + size > len(raw):
                raise InvalidRequest(field_name, "BYTES binary data cut short")
            out.append(raw[offset + 4 : offset + 4 + size].decode("utf-8", "replace"))
            offset += 4 + size
        return out
    if datatype not in _NUMPY:
        raise InvalidRequest(field_name, f"unsupported datatype {brief(datatype)}")
    width = np.dtype(_NUMPY[datatype]).itemsize
    if len(raw) % width:
        raise InvalidRequest(field_name, f"{len(raw)} bytes of binary data are not {datatype}")
    return np.frombuffer(raw, dtype=_NUMPY[datatype])


def encode_raw(datatype: str, data: np.ndarray) -> bytes:
    """An output's elements in the protocol's binary form (little-endian)."""
    return data.astype(_NUMPY[datatype]).tobytes()


def _observations(tensor: Tensor) -> np.ndarray:
    field_name = f"inputs[{tensor.name}]"
    if tensor.datatype not in ("FP32", "FP64"):
        raise InvalidRequest(field_name, f"expected datatype FP32 or FP64, got {tensor.datatype}")
    if len(tensor.shape) not in (1, 2) or any(d < 1 for d in tensor.shape):
        raise InvalidRequest(field_name, f"expected shape [D] or [B, D], got {list(tensor.shape)}")
    data = np.asarray(tensor.data, dtype=np.float64)
    if data.size != int(np.prod(tensor.shape)):
        raise InvalidRequest(
            field_name, f"{data.size} elements do not fill shape {list(tensor.shape)}"
        )
    return data.reshape(-1, tensor.shape[-1])


def _strings(tensor: Tensor) -> list[str]:
    if tensor.datatype != "BYTES":
        raise InvalidRequest(f"inputs[{tensor.name}]", f"expected BYTES, got {tensor.datatype}")
    return [str(s) for s in tensor.data]


def inference(
    env: str,
    version: str | None,
    tensors: Sequence[Tensor],
    parameters: Mapping[str, Any],
    requested: Sequence[tuple[str, Mapping[str, Any]]] | None = None,
) -> Inference:
    """The decoded v2 inference on model `env` (module docstring)."""
    check_model(env, version)
    settings, binary = split_parameters(parameters)
    outputs = requested_outputs(requested, binary)
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
    act = ActRequest(
        env=env,
        ego_goal=settings.pop("ego_goal"),
        observations=_observations(by_name["observation"]),
        partners=tuple(PartnerSpec(k + 1, goal=g) for k, g in enumerate(partners)),
        **settings,
    )
    return Inference(act, outputs)


def infer(
    engine: InferenceEngine, request: ActRequest, statistics: Statistics | None = None
) -> list[ActResult]:
    """The engine's answer, counted in `statistics`; its errors about `observations[b]` blame
    the v2 input instead (`inputs[observation][b]`), the name the client sent."""
    start = time.perf_counter_ns()
    try:
        results = engine.act(request)
    except EngineError as err:
        if statistics is not None:
            statistics.record(request.env, 0, time.perf_counter_ns() - start, ok=False)
        if err.field is None or not err.field.startswith("observations"):
            raise
        raise err.renamed("inputs[observation]" + err.field.removeprefix("observations")) from None
    if statistics is not None:
        statistics.record(request.env, len(results), time.perf_counter_ns() - start, ok=True)
    return results


def outputs(
    results: Sequence[ActResult], names: Sequence[str] = OUTPUT_NAMES
) -> list[tuple[str, str, list[int], np.ndarray]]:
    """(name, datatype, shape, flat data) of each output named, in that order."""
    rows = len(results)
    made: dict[str, tuple[str, list[int], Any]] = {
        "probabilities": ("FP64", [], lambda: np.asarray([r.probs for r in results], np.float64)),
        "action": ("INT64", [rows], lambda: np.asarray([r.action for r in results], np.int64)),
        "greedy_action": (
            "INT64",
            [rows],
            lambda: np.asarray([r.greedy_action for r in results], np.int64),
        ),
    }
    answer = []
    for name in names:
        datatype, shape, build = made[name]
        data = build()
        answer.append((name, datatype, shape or list(data.shape), data.ravel()))
    return answer


@dataclass
class _Counts:
    success: int = 0
    success_ns: int = 0
    fail: int = 0
    fail_ns: int = 0
    rows: int = 0
    last_ms: int = 0


@dataclass
class Statistics:
    """This process's v2 inferences per model (Triton's statistics extension): requests that
    reached the engine, with the time the engine took, and the rows they inferred. Several
    workers (`--workers N`) each count their own, as the engine's figures in /metrics."""

    _counts: dict[str, _Counts] = field(default_factory=dict)
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def record(self, env: str, rows: int, ns: int, *, ok: bool) -> None:
        with self._lock:
            counts = self._counts.setdefault(env, _Counts())
            if ok:
                counts.success += 1
                counts.success_ns += ns
                counts.rows += rows
            else:
                counts.fail += 1
                counts.fail_ns += ns
            counts.last_ms = int(time.time() * 1000)

    def model_stats(self, env: str | None = None, version: str | None = None) -> list[dict]:
        """Triton's `model_stats` entries: of model `env`, or of every model."""
        if env is not None:
            check_model(env, version)
        envs = [env] if env is not None else list(known_envs())
        with self._lock:
            counts = {e: self._counts.get(e, _Counts()) for e in envs}
        zero = {"count": 0, "ns": 0}
        return [
            {
                "name": e,
                "version": MODEL_VERSION,
                "last_inference": c.last_ms,
                "inference_count": c.rows,
                "execution_count": c.success,
                "inference_stats": {
                    "success": {"count": c.success, "ns": c.success_ns},
                    "fail": {"count": c.fail, "ns": c.fail_ns},
                    "queue": dict(zero),
                    "compute_input": dict(zero),
                    "compute_infer": {"count": c.success, "ns": c.success_ns},
                    "compute_output": dict(zero),
                    "cache_hit": dict(zero),
                    "cache_miss": dict(zero),
                },
                "batch_stats": [],
            }
            for e, c in counts.items()
        ]


STATISTICS = Statistics()  # the process's one record, shared by the REST and gRPC transports
