"""Fixtures of the `coexist` command's tests (`cli/`): the service tests' helpers and tiny zoo.

The commands are tested as a user runs them, against real servers (`coexist serve`, the jobs
and registry APIs), so these tests start those servers with the helpers that `tests/services/`
keeps for its own tests (`serve_process`, `http_live_server`, `live_serve`, `replica_cluster`,
`console_zoo`, `jobs_fakes`, `zoo_fixtures`): that folder goes on `sys.path` here, as its own
conftest puts it there for the tests below it.
"""

import sys
from pathlib import Path

SERVICE_HELPERS = Path(__file__).resolve().parents[1] / "services"
if str(SERVICE_HELPERS) not in sys.path:
    sys.path.insert(0, str(SERVICE_HELPERS))

from zoo_fixtures import _tiny_zoo_template, tiny_zoo, tiny_zoo_store  # noqa: E402, F401
