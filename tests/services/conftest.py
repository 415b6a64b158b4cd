"""Fixtures of the service tests, in every sub-folder: the tiny zoo (`zoo_fixtures`).

This folder is on `sys.path` for every test below it (pytest puts a conftest's folder there), so
the helpers that several sub-folders share (`grpc_live_server`, `http_live_server`,
`live_serve`, `replica_cluster`, `session_zoo`, `console_zoo`, `jobs_fakes`, `tls_certs`,
`zoo_fixtures`) live here and are imported by their bare names.
"""

from zoo_fixtures import _tiny_zoo_template, act_client, tiny_zoo, tiny_zoo_store  # noqa: F401
