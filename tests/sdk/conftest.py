"""Fixtures of the SDK tests: the clients run against real servers, built by the helpers of
tests/services (shared with the transports' tests), whose folder goes on `sys.path` here."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "services"))

from zoo_fixtures import _tiny_zoo_template  # noqa: F401
