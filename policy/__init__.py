"""Pure policy maths of AAIL and the Q-network, shared by the trainer and the inference services.

No I/O and no state: every function maps arrays to arrays. The paper's equations live here.

| module      | what                                                             | needs  |
|-------------|------------------------------------------------------------------|--------|
| `maths`     | soft value (eq. 3), Boltzmann policy (eq. 2), normalised entropy,| numpy  |
|             | Jensen-Shannon distance (eq. 10), task weight (eq. 9)            |        |
| `blend`     | SL / NAIL / AAIL blending of task and impact Q (eq. 8), goal     | numpy  |
|             | beliefs mixed into one impact Q per partner                      |        |
| `regret_bound` | AAIL-B's bound on the ego's one-step regret (eq. R1) and its  | numpy  |
|             | goal-keeping rule (R4)                                           |        |
| `regret_budget` | AAIL within an episode's regret budget (eqs. B1-B4)          | numpy  |
| `belief`    | goal belief from observed actions: prior, Boltzmann likelihoods  | numpy  |
|             | (eq. 2), update with forgetting and floor, blend distribution    |        |
| `torch_ops` | soft value, Boltzmann policy and sampling in torch (trainer)     | torch  |
| `qnet`      | `QNetSpec` (JSON architecture spec), `QNetwork`, `StackedQNet`,  | torch  |
|             | safetensors I/O, numpy stacked forward for serving               |        |

`import policy` loads only numpy; the torch-based names are imported on first use.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from policy.belief import (
    BeliefConfig,
    blend_goal_probs,
    boltzmann_log_likelihoods,
    initial_log_belief,
    prior_log_probs,
    update_log_belief,
)
from policy.blend import METHODS, BlendMethod, BlendResult, blend, mix_goal_beliefs
from policy.maths import boltzmann, js_distance, normalized_entropy, soft_value, task_weight

if TYPE_CHECKING:
    from policy.qnet import (
        QNetSpec,
        QNetwork,
        StackedQNet,
        numpy_stacked_forward,
        qnet_from_safetensors,
        stack_numpy,
        tensors_from_safetensors,
        weights_to_safetensors,
    )
    from policy.torch_ops import boltzmann_t, sample_boltzmann_t, soft_value_t

_LAZY = {
    "QNetSpec": "policy.qnet",
    "QNetwork": "policy.qnet",
    "StackedQNet": "policy.qnet",
    "numpy_stacked_forward": "policy.qnet",
    "qnet_from_safetensors": "policy.qnet",
    "stack_numpy": "policy.qnet",
    "tensors_from_safetensors": "policy.qnet",
    "weights_to_safetensors": "policy.qnet",
    "boltzmann_t": "policy.torch_ops",
    "sample_boltzmann_t": "policy.torch_ops",
    "soft_value_t": "policy.torch_ops",
}

# the torch-based names (see _LAZY) are imported on first access
__all__ = [
    "METHODS",
    "BeliefConfig",
    "BlendMethod",
    "BlendResult",
    "QNetSpec",
    "QNetwork",
    "StackedQNet",
    "blend",
    "blend_goal_probs",
    "boltzmann",
    "boltzmann_log_likelihoods",
    "boltzmann_t",
    "initial_log_belief",
    "js_distance",
    "mix_goal_beliefs",
    "normalized_entropy",
    "numpy_stacked_forward",
    "prior_log_probs",
    "qnet_from_safetensors",
    "sample_boltzmann_t",
    "soft_value",
    "soft_value_t",
    "stack_numpy",
    "task_weight",
    "tensors_from_safetensors",
    "update_log_belief",
    "weights_to_safetensors",
]


def __getattr__(name: str) -> Any:
    """Import the torch-based names on first access (PEP 562), keeping `import policy` light."""
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'policy' has no attribute {name!r}")
