"""`/docs` renders Swagger UI with the network cut off: headless Chromium (Playwright) loads the
page of a real `coexist serve` while every request to another origin is refused, and the
operations of the API appear; the page names only the server's own assets."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import httpx
import pytest
from console.console_browser import launch_chromium, sync_playwright
from live_serve import serving, zoo_copy
from replica_cluster import Server

# Chromium resolves no name at all, so even a request the route below missed goes nowhere
OFFLINE_ARGS = ("--host-resolver-rules=MAP * ~NOTFOUND , EXCLUDE 127.0.0.1",)


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory, _tiny_zoo_template: Path) -> Iterator[Server]:
    directory = tmp_path_factory.mktemp("docs-page")
    with serving(directory, zoo_copy(_tiny_zoo_template, directory / "store")) as running:
        yield running


def test_the_page_names_only_local_assets(server: Server) -> None:
    page = httpx.get(f"{server.http_url}/docs")
    assert page.status_code == 200 and "swagger-ui" in page.text
    assert "https://" not in page.text and "http://" not in page.text  # no CDN, no site
    for asset in ("swagger-ui-bundle.js", "swagger-ui.css"):
        answer = httpx.get(f"{server.http_url}/docs/assets/{asset}")
        assert answer.status_code == 200 and len(answer.content) > 10_000, asset


@pytest.mark.slow
def test_docs_render_in_chromium_with_the_network_cut_off(server: Server) -> None:
    origin = urlsplit(server.http_url).netloc
    elsewhere: list[str] = []

    def only_the_server(route: Any) -> None:
        if urlsplit(route.request.url).netloc == origin:
            route.continue_()
        else:
            elsewhere.append(route.request.url)
            route.abort("internetdisconnected")

    with sync_playwright() as playwright:
        browser = launch_chromium(playwright, OFFLINE_ARGS)
        try:
            page = browser.new_page()
            page.route("**/*", only_the_server)
            page.goto(f"{server.http_url}/docs")
            page.wait_for_selector(".opblock", timeout=30_000)
            paths = page.locator(".opblock-summary-path").all_inner_texts()
            assert any("/v1/act" in p for p in paths), paths[:10]
            assert page.locator(".swagger-ui .info .title").inner_text().startswith("coexist")
            assert elsewhere == []  # nothing even tried to leave the machine
        finally:
            browser.close()
