"""Types of the compiled blend (policy/_blend_row.c); `policy.blend.blend` is its interface."""

from typing import Any

def blend_rows(
    method: str,
    q_task_BA: Any,
    q_impact_BPA: Any,
    alpha_B: Any,
    mask_BP: Any,
    normalise: bool,
    epsilon_B: Any = None,
    /,
) -> tuple[Any, Any, Any, Any, Any]: ...
def sample_rows(probs_BA: Any, u_B: Any, /) -> tuple[Any, Any]: ...
