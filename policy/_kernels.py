"""The compiled kernels of `policy` (setup.py builds them where a C compiler exists)."""

from __future__ import annotations

import importlib
from typing import Any


def load_kernel(name: str) -> Any:
    """The extension module `policy.<name>`, or None where it was not built (the caller then
    runs its numpy reference)."""
    try:
        return importlib.import_module(f"policy.{name}")
    except ImportError:  # an install without a C compiler
        return None
