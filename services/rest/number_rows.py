"""`NumberRows`: a batch body's `observations`, read straight into a float64 matrix when they are
plain rows of numbers (the compiled `services.rest._number_rows`), validated as a `Matrix` by
pydantic otherwise.

Why: a large batch is as many lists of Python floats; validating them as `list[list[float]]`
copies every number into new lists and `np.asarray` then walks them again, a large share of a
batch request's time (docs/performance.md, "A faster REST batch"). The compiled pass takes only what pydantic would accept unchanged (exact floats and
ints, rows of equal length); anything else (a string, a bool, a ragged or empty batch, a
number beyond a double) goes the way it always went, so the same bodies are accepted, with the
same values and the same errors naming the entry. The schema (`openapi.json`) is `Matrix`'s.
Without a C compiler the module is not built and every body takes pydantic's way.
"""

from __future__ import annotations

import importlib
from typing import Annotated, Any

from pydantic import ValidatorFunctionWrapHandler, WrapValidator

from services.rest.bounded import Matrix


def _load() -> Any:
    try:
        return importlib.import_module("services.rest._number_rows")
    except ImportError:  # an install without a C compiler
        return None


_extension = _load()
COMPILED: bool = _extension is not None


def float_rows(value: Any) -> Any:
    """`value` as a (B, D) float64 array when it is a non-empty list of equal lists of exact
    floats and ints (module docstring), else None."""
    return None if _extension is None else _extension.float_rows(value)


def _rows_or_matrix(value: Any, handler: ValidatorFunctionWrapHandler) -> Any:
    rows = float_rows(value)
    return handler(value) if rows is None else rows


# the value is a float64 ndarray or (pydantic's way) a list of lists of floats
NumberRows = Annotated[Matrix, WrapValidator(_rows_or_matrix)]
