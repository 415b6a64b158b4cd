"""What the console's browser tests run against (imported by them; not a test module): a real
`coexist serve` process over the console zoo, and headless Chromium from Debian's packages
driven by Playwright.

    with serve_console(store_url, data_dir, admin=..., read=...) as url: ...
    browser = launch_chromium(playwright)   # skips without a browser, fails in CI
    screenshot(page, screenshot_dir(tmp_path_factory), "registry")

No browser is ever downloaded: Playwright drives `/usr/bin/chromium` (apt package `chromium`,
installed by `scripts/test.sh`). Outside CI a machine without it skips these tests; in CI
(`CI=true`) they fail instead, as the PostgreSQL tests do with `COEXIST_REQUIRE_POSTGRES`.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import httpx
import pytest
from serve_process import free_port, serve_command

CHROMIUM = os.environ.get("COEXIST_CHROMIUM", "/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
VIEWPORT = {"width": 1366, "height": 768}  # a laptop screen
# Where screenshots go: docs/console with COEXIST_SCREENSHOT_DIR=docs/console (the README's come
# from such a run). Not by default: a tracked file rewritten mid-run makes the checkout "dirty",
# and processes that record `git describe --dirty` as lineage would disagree (trainer tests).
SCREENSHOT_DIR = os.environ.get("COEXIST_SCREENSHOT_DIR")


def _unavailable(reason: str) -> None:
    if os.environ.get("CI") == "true":
        pytest.fail(f"browser tests cannot run in CI: {reason}")
    pytest.skip(reason)


def launch_chromium(playwright: Any, extra_args: tuple[str, ...] = ()) -> Any:
    """Headless Chromium from Debian's package (with `extra_args` on its command line); skip
    (fail in CI) when it is missing."""
    if not Path(CHROMIUM).is_file() and shutil.which("chromium") is None:
        _unavailable(f"no Chromium at {CHROMIUM} (apt-get install chromium)")
    path = CHROMIUM if Path(CHROMIUM).is_file() else str(shutil.which("chromium"))
    return playwright.chromium.launch(executable_path=path, args=[*CHROMIUM_ARGS, *extra_args])


def sync_playwright() -> Any:
    """Playwright's sync API; skip (fail in CI) when the `dev` extra is not installed."""
    try:
        from playwright.sync_api import sync_playwright as start
    except ImportError:
        _unavailable("playwright is not installed (pip install -e '.[dev]')")
    return start()


@contextmanager
def serve_console(store_url: str, data_dir: Path, *, admin: str, read: str) -> Iterator[str]:
    """`coexist serve` (REST only) over `store_url`, reads behind `read`; yields its URL."""
    port = free_port()
    env = {
        **{k: v for k, v in os.environ.items() if not k.startswith("COEXIST_")},
        "COEXIST_ADMIN_TOKEN": admin,
        "COEXIST_READ_TOKEN": read,
        "COEXIST_DATA_DIR": str(data_dir),
        "COEXIST_REFRESH_INTERVAL_S": "0.5",
        "COEXIST_LOG_LEVEL": "warning",
    }
    cmd = serve_command(store_url, port)
    log = (data_dir / "serve.log").open("wb")
    process = subprocess.Popen(cmd, env=env, stdout=log, stderr=subprocess.STDOUT)
    url = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 60
        while True:
            assert process.poll() is None, (data_dir / "serve.log").read_text()
            try:
                if httpx.get(f"{url}/readyz", timeout=1.0).status_code == 200:
                    break
            except httpx.TransportError:
                pass
            assert time.monotonic() < deadline, "coexist serve did not become ready"
            time.sleep(0.2)
        yield url
    finally:
        process.send_signal(signal.SIGTERM)
        try:
            process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            process.kill()
        log.close()


def screenshot_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """`COEXIST_SCREENSHOT_DIR` (relative to the repository) or a temporary directory."""
    if SCREENSHOT_DIR:
        return Path(__file__).resolve().parents[3] / SCREENSHOT_DIR
    return tmp_path_factory.mktemp("console_screenshots")


def screenshot(page: Any, directory: Path, name: str, *, full_page: bool = False) -> Path:
    """Save a screenshot of the page as `<directory>/<name>.png`."""
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / f"{name}.png"
    page.screenshot(path=str(path), full_page=full_page)
    assert path.stat().st_size > 0
    return path
