"""Suite-wide settings.

pytest runs with `-n 2` (two worker processes on a 2-core machine). torch's default of one
thread per core then oversubscribes the CPU, and small batched updates slowed down twentyfold in
that state (benchmarks/training.py measures it): every worker uses one torch thread.
"""

import torch

torch.set_num_threads(1)

# The plugin distribution's own tests (tests/envs/tinyline/tests) run only with it installed, as
# its author runs them: tests/cli/test_plugin_end_to_end.py installs it and runs them.
collect_ignore = ["envs/tinyline"]


# --- the tiny plugin distribution of tests/envs/tinyline (an environment and a store backend) ---

from collections.abc import Iterator  # noqa: E402
from pathlib import Path  # noqa: E402

import pytest  # noqa: E402

TINYLINE_ROOT = Path(__file__).resolve().parent / "envs" / "tinyline"


@pytest.fixture
def tinyline() -> Iterator[str]:
    """The corridor environment of tests/envs/tinyline registered in this process by code
    (`register_env`; the end-to-end tests install it and find it by its entry point instead);
    yields its name and forgets it afterwards."""
    import sys

    from envs.registry import register_env, unregister_env

    sys.path.insert(0, str(TINYLINE_ROOT))
    try:
        from tinyline.plugin import ENV

        register_env(ENV, replace=True)
        yield ENV.name
    finally:
        unregister_env("tinyline")
        sys.path.remove(str(TINYLINE_ROOT))
