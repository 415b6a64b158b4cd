"""The installed version of coexist (one source: the repository's VERSION file)."""

from __future__ import annotations

from importlib import metadata
from pathlib import Path


def _version() -> str:
    try:
        return metadata.version("coexist")
    except metadata.PackageNotFoundError:  # a checkout that was not installed
        file = Path(__file__).resolve().parents[1] / "VERSION"
        return file.read_text().strip() if file.exists() else "0+unknown"


VERSION = _version()
