"""Fixtures of the documentation's tests: the service tests' helpers (a real `coexist serve`, the
console zoo) go on `sys.path`, as `tests/cli/conftest.py` puts them there for the CLI's tests."""

import sys
from pathlib import Path

SERVICE_HELPERS = Path(__file__).resolve().parents[1] / "services"
if str(SERVICE_HELPERS) not in sys.path:
    sys.path.insert(0, str(SERVICE_HELPERS))
