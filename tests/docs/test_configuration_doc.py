"""docs/configuration.md is the settings table of `services/settings.py`, up to date, and that
table has a row for every field of `Settings`."""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

from services.settings import Settings

ROOT = Path(__file__).resolve().parents[2]


def _generator():
    spec = importlib.util.spec_from_file_location(
        "gen_config_doc", ROOT / "scripts" / "gen_config_doc.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_page_is_generated_from_the_settings_table() -> None:
    page = (ROOT / "docs" / "configuration.md").read_text()
    assert page == _generator().render(), "run: python scripts/gen_config_doc.py"


def test_every_setting_has_a_row() -> None:
    documented = set(re.findall(r"`COEXIST_([A-Z0-9_]+)`", _generator().settings_table()))
    fields = {name.upper() for name in Settings.model_fields}
    assert fields - documented == set(), "settings without a row in services/settings.py"
