"""Write docs/configuration.md from the one table of settings in `services/settings.py`'s
docstring (run after changing a setting; `tests/docs/test_configuration_doc.py` checks that the
file is up to date and that every `Settings` field has its row)."""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

HEADER = """# Configuration

Every setting is a `COEXIST_*` environment variable (the servers read them through
`services.settings.Settings`, pydantic-settings). This page is generated from the table in
`services/settings.py` by `python scripts/gen_config_doc.py`; the test suite checks that it is up
to date and that every field of `Settings` has a row.

"""


def settings_table() -> str:
    """The docstring of `services.settings` from its table's header to the end of the table."""
    import services.settings as settings

    lines = (settings.__doc__ or "").splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("| variable"))
    end = next((i for i in range(start, len(lines)) if not lines[i].startswith("|")), len(lines))
    rest = "\n".join(lines[end:]).strip()
    return "\n".join(lines[start:end]) + "\n\n" + rest + "\n"


def render() -> str:
    return HEADER + settings_table()


if __name__ == "__main__":
    (ROOT / "docs" / "configuration.md").write_text(render())
