"""Validation of an artifact (architecture spec + safetensors weights) before it is stored.

The store never trusts an upload: the spec must parse (`policy.qnet.QNetSpec.from_json`), agree
with the registered model's observation and action sizes, and the weights must be a well-formed
safetensors file whose tensors are exactly the spec's (names, shapes, dtype float32/float16/
bfloat16, all finite). Every failure is an `InvalidArtifact` naming the field or tensor.
The weights are parsed by the safetensors library, never unpickled.
"""

from __future__ import annotations

import hashlib
import json
import sys
from dataclasses import dataclass
from typing import Any

from model_store.entities import Lineage
from model_store.errors import ArtifactTooLarge, InvalidArtifact, brief
from model_store.naming import parse_ref


@dataclass(frozen=True)
class CheckedArtifact:
    spec: dict[str, Any]
    sha256: str
    size_bytes: int


def sha256_hex(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def check_artifact(
    spec: dict[str, Any],
    weights: bytes,
    *,
    obs_dim: int,
    n_actions: int,
    max_bytes: int,
) -> CheckedArtifact:
    """Validate `spec` and `weights` for a model with the given sizes; InvalidArtifact if not."""
    # Imported here: policy.qnet pulls in numpy only, but the store module stays light to import.
    from policy.qnet import QNetSpec, tensors_from_safetensors

    if not isinstance(weights, bytes | bytearray | memoryview):
        raise InvalidArtifact("weights: expected the bytes of a safetensors file", field="weights")
    weights = bytes(weights)
    if len(weights) > max_bytes:
        raise ArtifactTooLarge(
            f"weights: {len(weights)} bytes is over this store's limit of {max_bytes} bytes",
            field="weights",
        )
    if not isinstance(spec, dict):
        raise InvalidArtifact("spec: expected a JSON object", field="spec")
    try:
        parsed = QNetSpec.from_json(spec)
    except (ValueError, TypeError, KeyError) as exc:
        raise InvalidArtifact(f"spec: {exc}", field="spec") from None
    for key, expected in (("obs_dim", obs_dim), ("n_actions", n_actions)):
        got = spec.get(key)
        if got != expected:
            raise InvalidArtifact(
                f"spec.{key}: the model is registered with {key}={expected}, the spec says {got}",
                field=f"spec.{key}",
            )
    try:
        tensors_from_safetensors(parsed, weights)
    except (ValueError, TypeError) as exc:
        raise InvalidArtifact(f"weights: {exc}", field="weights") from None
    return CheckedArtifact(spec=dict(spec), sha256=sha256_hex(weights), size_bytes=len(weights))


def check_lineage(lineage: Lineage) -> Lineage:
    """JSON-safe config/metrics (no NaN/inf), parents as 'name/version' refs."""
    if not isinstance(lineage, Lineage):
        raise InvalidArtifact("lineage: expected a Lineage", field="lineage")
    if isinstance(lineage.metrics, dict) and "training_curve" in lineage.metrics:
        check_training_curve(lineage.metrics["training_curve"])  # first: it names the entry
    for key in ("config", "metrics"):
        value = getattr(lineage, key)
        try:
            json.dumps(value, allow_nan=False)
        except (TypeError, ValueError) as exc:
            raise InvalidArtifact(
                f"lineage.{key}: not plain JSON without NaN/inf ({exc})", field=f"lineage.{key}"
            ) from None
    for i, parent in enumerate(lineage.parents):
        field = f"lineage.parents[{i}]"
        ref = parse_ref(parent, field)
        if ref.version is None:
            raise InvalidArtifact(
                f"{field}: expected 'name/version', got {brief(parent)}", field=field
            )
    return lineage


def check_training_curve(curve: Any) -> None:
    """`metrics.training_curve` (what the console draws): an object of equally long lists of
    finite numbers (`steps`, `mean_return`, `loss`, ...); `steps` whole numbers >= 0.
    InvalidArtifact naming the first bad entry: a string or NaN there would be drawn as NaN."""
    field = "lineage.metrics.training_curve"
    if not isinstance(curve, dict):
        raise InvalidArtifact(f"{field}: expected an object of lists of numbers", field=field)
    lengths = set()
    for key, values in curve.items():
        plain = isinstance(key, str) and key.isidentifier() and len(key) <= 40
        where = f"{field}.{key if plain else brief(key, 40)}"
        if not isinstance(values, list):
            raise InvalidArtifact(f"{where}: expected a list of numbers", field=where)
        lengths.add(len(values))
        for i, value in enumerate(values):
            number = isinstance(value, int | float) and not isinstance(value, bool)
            finite = number and abs(value) <= sys.float_info.max  # NaN fails it too
            if not finite or (key == "steps" and not _step(value)):
                expected = "a whole number >= 0" if key == "steps" else "a finite number"
                raise InvalidArtifact(
                    f"{where}[{i}]: expected {expected}, got {brief(value)}", field=f"{where}[{i}]"
                )
    if len(lengths) > 1:
        raise InvalidArtifact(
            f"{field}: its lists differ in length ({sorted(lengths)}): one value per point",
            field=field,
        )


def _step(value: float) -> bool:
    whole = isinstance(value, int) or value.is_integer()  # no float(): an int may be huge
    return whole and value >= 0
