"""`NumberRows` and `NumberStates`: a batch body's `observations` (rows of numbers) and `states`
(one row per agent, per state), read straight into a float64 array when they are plain
numbers (the compiled `services.rest._number_rows`), validated by pydantic as a `Matrix` or a
`Tensor3` otherwise.

Why: a large batch is as many lists of Python floats; validating them as `list[list[float]]`
copies every number into new lists and `np.asarray` then walks them again, a large share of a
batch request's time (docs/performance.md, "Where the time goes"). The compiled pass takes
only what pydantic would accept unchanged (exact floats and ints, lists of equal length at
every level); anything else (a string, a bool, ragged rows, an empty batch, a number beyond a
double) goes the way it always went, so the same bodies are accepted, with the same values
and the same errors naming the entry. The schema (`openapi.json`) is `Matrix`'s or
`Tensor3`'s. Without a C compiler the module is not built and every body takes pydantic's way.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Annotated, Any

from pydantic import ValidatorFunctionWrapHandler, WrapValidator

from services.rest.bounded import Matrix, Tensor3


def _load() -> Any:
    try:
        return importlib.import_module("services.rest._number_rows")
    except ImportError:  # an install without a C compiler
        return None


_extension = _load()
COMPILED: bool = _extension is not None


def float_array(value: Any, ndim: int) -> Any:
    """`value` as a float64 array of `ndim` dimensions when it is `ndim` levels of non-empty
    lists of equal lengths of exact floats and ints (module docstring), else None."""
    return None if _extension is None else _extension.float_array(value, ndim)


def _array_or_lists(ndim: int) -> Callable[[Any, ValidatorFunctionWrapHandler], Any]:
    def validate(value: Any, handler: ValidatorFunctionWrapHandler) -> Any:
        array = float_array(value, ndim)
        return handler(value) if array is None else array

    return validate


# the value is a float64 ndarray or (pydantic's way) nested lists of floats
NumberRows = Annotated[Matrix, WrapValidator(_array_or_lists(2))]
NumberStates = Annotated[Tensor3, WrapValidator(_array_or_lists(3))]
