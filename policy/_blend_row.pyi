"""Types of the compiled row blend (policy/_blend_row.c); `policy.blend_fast` is its interface."""

from collections.abc import Sequence
from typing import Any

def blend_row(
    method: str,
    q_task_A: Sequence[float],
    q_impact_PA: Sequence[Sequence[float]],
    alpha: float,
    mask_P: Sequence[bool] | None,
    normalise: bool,
    /,
) -> Any: ...
def blend_rows(
    method: str,
    q_task_BA: Any,
    q_impact_BPA: Any,
    alpha_B: Any,
    mask_BP: Any,
    normalise: bool,
    /,
) -> Any: ...
def set_result_type(result_type: type, /) -> None: ...
