"""The optional compiled parts of `policy` (setup.py builds them where a C compiler exists).

`load("_row_forward", "COEXIST_PYTHON_FORWARD")` is the extension module, or None when it was
not built or when the environment variable asks for the Python/numpy path (any value but
empty or "0", read once at import: an A/B switch, as COEXIST_PYTHON_BLEND is for the blend).
"""

from __future__ import annotations

import importlib
import os
from types import ModuleType


def load(name: str, switch: str) -> ModuleType | None:
    if os.environ.get(switch, "") not in ("", "0"):
        return None
    try:
        return importlib.import_module(f"policy.{name}")
    except ImportError:  # built without a C compiler
        return None
