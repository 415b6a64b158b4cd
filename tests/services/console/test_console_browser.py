"""The web console in a real browser (headless Chromium, Playwright) against a real `coexist
serve` whose reads need a token: the registry lists the zoo, promoting through the page moves
the alias (checked over REST), the change feed is live, a wrong token is refused, live particle
and kitchen episodes render, SL and AAIL differ side by side, a link reproduces an episode, and
a training job is submitted, followed and cancelled. Screenshots: `console_browser.screenshot_dir`
(COEXIST_SCREENSHOT_DIR=docs/console refreshes the README's)."""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from console_browser import (
    VIEWPORT,
    launch_chromium,
    screenshot,
    screenshot_dir,
    serve_console,
    sync_playwright,
)
from console_zoo import build_console_zoo

from model_store.entities import Lineage
from model_store.sql import SqlModelStore
from model_store.testing import qnet_spec, qnet_weights

ADMIN, READ = "browser-admin-t0ken", "browser-read-t0ken"
# a non-aligned pair (a1's target and d3's influence area do not overlap) whose episode with
# this seed keeps both agents moving for the first 25 steps in the test zoo
EPISODE = "env=particle&ego_goal=a1&partners=d3&seed=4&max_steps=60"
KITCHEN = "env=cooking&ego_goal=TomatoLettuceSalad&partners=CarrotBanana&seed=0&max_steps=30"
WAIT_MS = 30_000

READ_LANES = """() => ({
  t: Number(document.querySelector("#player").dataset.t),
  lanes: [...document.querySelectorAll(".lane")].map((lane) => {
    const sum = (root) => [...root.querySelectorAll("li.bar")]
      .reduce((s, li) => s + Number(li.dataset.value), 0);
    return {
      method: lane.dataset.method,
      agents: [...lane.querySelectorAll("circle.agent-disc")]
        .map((c) => [Number(c.dataset.x), Number(c.dataset.y)]),
      bars: [...lane.querySelectorAll(".agent-panel")].map(sum),
      beliefs: [...lane.querySelectorAll("div.belief")].map(sum),
      returns: lane.querySelector(".lane-returns").textContent,
    };
  }),
})"""


def _expect() -> Any:
    from playwright.sync_api import expect

    return expect


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, str]]:
    root = tmp_path_factory.mktemp("console_browser")
    store_url = build_console_zoo(root / "models.db")
    with serve_console(store_url, root, admin=ADMIN, read=READ) as url:
        yield {"url": url, "store_url": store_url}


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    with sync_playwright() as playwright:
        chromium = launch_chromium(playwright)
        yield chromium
        chromium.close()


@pytest.fixture(scope="module")
def shots(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return screenshot_dir(tmp_path_factory)


@pytest.fixture
def open_page(browser: Any, server: dict[str, str]) -> Iterator[Any]:
    """`open_page(route, token=READ)`: a fresh laptop-sized tab at `/console/#/route`, the token
    already in its session storage; uncaught script errors fail the test."""
    pages: list[Any] = []
    errors: list[str] = []

    def open_(route: str, token: str | None = READ) -> Any:
        page = browser.new_page(viewport=VIEWPORT)
        page.on("pageerror", lambda exc: errors.append(str(exc)))
        if token:
            page.add_init_script(f"sessionStorage.setItem('coexist.token', {token!r});")
        page.goto(f"{server['url']}/console/#/{route}")
        pages.append(page)
        return page

    yield open_
    for page in pages:
        page.close()
    assert not errors, errors


def _rest(server: dict[str, str], path: str) -> Any:
    headers = {"Authorization": f"Bearer {ADMIN}"}
    answer = httpx.get(f"{server['url']}{path}", headers=headers, timeout=10)
    answer.raise_for_status()
    return answer.json()


def _use_token(page: Any, token: str) -> None:
    page.fill("#token", token)
    page.click("#token-form button[type=submit]")


def test_the_registry_lists_the_zoo_with_lineage(
    open_page: Any, server: dict[str, str], shots: Path
) -> None:
    expect = _expect()
    page = open_page("registry")
    names = [m["name"] for m in _rest(server, "/v1/registry/models?page_size=1000")["models"]]
    expect(page.locator("#models-caption")).to_have_text(f"Models: {len(names)} of {len(names)}")
    rows = page.locator("#models-table tbody tr")
    assert rows.evaluate_all("(rows) => rows.map((r) => r.dataset.model)") == names
    page.locator("#filter-kind").select_option("impact")
    page.locator("#filter-text").fill("b3")
    expect(rows).to_have_count(1)
    page.get_by_role("link", name="particle/impact/b3").click()
    expect(page.locator("#model-title")).to_have_text("particle/impact/b3")
    page.locator("#model-detail").get_by_role("link", name="v2").click()
    lineage = page.locator(".lineage")
    expect(lineage).to_contain_text("registered by")
    points = lineage.locator("polyline.series").get_attribute("points") or ""
    assert len(points.split()) == 5  # the curve registered with the version, point for point
    screenshot(page, shots, "registry", full_page=True)
    lineage.get_by_role("link", name="particle/task/b3/1").click()  # the parent network
    expect(page.locator("#model-title")).to_have_text("particle/task/b3")
    expect(page.locator(".lineage h4")).to_have_text("particle/task/b3 v1: lineage")


def test_promoting_through_the_page_moves_the_alias(open_page: Any, server: dict[str, str]) -> None:
    expect = _expect()
    page = open_page("registry?model=particle%2Ftask%2Fa2", token=None)
    _use_token(page, ADMIN)  # through the form, as a person would
    expect(page.locator("#model-title")).to_have_text("particle/task/a2")
    page.get_by_role("button", name="Promote to production: particle/task/a2 version 2").click()
    expect(page.locator("#notice")).to_contain_text("production now points at v2")
    assert _rest(server, "/v1/registry/models/particle/task/a2")["aliases"]["production"] == 2
    # the change feed shows it, and the table too, without a reload
    expect(page.locator("#feed")).to_contain_text("particle/task/a2: production → v2")
    row = page.locator('#models-table tr[data-model="particle/task/a2"] td.aliases')
    expect(row).to_contain_text("production: v2")


def test_a_token_given_while_the_first_load_is_refused_opens_the_view(
    browser: Any, server: dict[str, str]
) -> None:
    """The page's first requests, sent without a token, are still in flight when the token is
    submitted (held back here until then): their refusal must not answer the view the token
    opens, nor stay on the notice line."""
    expect = _expect()
    page = browser.new_page(viewport=VIEWPORT)
    held: list[Any] = []

    def hold_tokenless(route: Any) -> None:
        if "authorization" in route.request.headers:
            route.continue_()
        else:
            held.append(route)

    page.route("**/v1/envs", hold_tokenless)
    try:
        page.goto(f"{server['url']}/console/#/registry?model=particle%2Ftask%2Fa2")
        for _ in range(200):  # until the tokenless request is held (bounded: 10 s)
            if held:
                break
            page.wait_for_timeout(50)
        assert held, "the page sent no tokenless /v1/envs"
        _use_token(page, ADMIN)
        for route in held:
            route.continue_()  # the refusal (401) arrives after the token was set
        expect(page.locator("#model-title")).to_have_text("particle/task/a2")
        expect(page.locator("#notice")).to_be_hidden()
    finally:
        page.close()


def test_changes_made_elsewhere_appear_without_a_reload(
    open_page: Any, server: dict[str, str]
) -> None:
    expect = _expect()
    page = open_page("registry?model=particle%2Ftask%2Fe0")
    expect(page.locator("#model-title")).to_have_text("particle/task/e0")
    answer = httpx.put(
        f"{server['url']}/v1/registry/models/particle/task/c1/-/aliases/staging",
        json={"version": 1},
        headers={"Authorization": f"Bearer {ADMIN}"},
    )
    assert answer.status_code == 200
    spec = qnet_spec(obs_dim=8, n_actions=5, hidden=(16,))
    with SqlModelStore(server["store_url"]) as store:  # another process registers a version
        store.register_version(
            "particle/task/e0",
            spec=spec,
            weights=qnet_weights(spec, seed=3),
            lineage=Lineage(registered_by="pytest"),
            aliases=("latest",),
        )
    expect(page.locator("#feed")).to_contain_text("particle/task/c1: staging → v1")
    expect(page.locator("#feed")).to_contain_text("particle/task/e0 v2 registered")
    staging = page.locator('#models-table tr[data-model="particle/task/c1"] td.aliases')
    expect(staging).to_contain_text("staging: v1")
    expect(page.locator('.versions-table tr[data-version="2"]')).to_contain_text("latest")


def test_archive_and_delete_through_the_page(open_page: Any, server: dict[str, str]) -> None:
    expect = _expect()
    spec = qnet_spec(obs_dim=8, n_actions=5, hidden=(16,))
    with SqlModelStore(server["store_url"]) as store:  # a version no alias points at
        version = store.register_version(
            "particle/task/d4",
            spec=spec,
            weights=qnet_weights(spec, seed=4),
            lineage=Lineage(registered_by="pytest"),
            aliases=(),
        ).version
    page = open_page("registry?model=particle%2Ftask%2Fd4", token=ADMIN)
    row = page.locator(f'.versions-table tr[data-version="{version}"]')
    row.get_by_role("button", name=f"Archive particle/task/d4 version {version}").click()
    expect(row.locator("td").first).to_have_text("archived")
    path = f"/v1/registry/models/particle/task/d4/-/versions/{version}"
    assert _rest(server, path)["status"] == "archived"
    row.get_by_role("button", name=f"Delete particle/task/d4 version {version}").click()
    row.get_by_role("button", name=f"Yes, delete v{version}").click()  # asked first
    expect(page.locator("#notice")).to_contain_text(f"deleted v{version}")
    expect(row).to_have_count(0)
    headers = {"Authorization": f"Bearer {ADMIN}"}
    assert httpx.get(f"{server['url']}{path}", headers=headers).status_code == 404


def test_a_wrong_token_is_refused_on_the_page(open_page: Any, server: dict[str, str]) -> None:
    expect = _expect()
    page = open_page("registry", token=None)
    expect(page.locator("#notice")).to_contain_text("Refused (401)")  # reads need a token here
    _use_token(page, "not-the-token")
    expect(page.locator("#notice")).to_contain_text("Refused (403)")
    expect(page.locator("#models-table tbody tr")).to_have_count(0)
    _use_token(page, READ)
    expect(page.locator("#models-table tbody tr").first).to_be_visible()
    page.goto(f"{server['url']}/console/#/registry?model=particle%2Fimpact%2Fb3")
    page.get_by_role("button", name="Promote to production: particle/impact/b3 version 2").click()
    expect(page.locator("#notice")).to_contain_text("Refused (403): the token is not valid")
    assert _rest(server, "/v1/registry/models/particle/impact/b3")["aliases"]["production"] == 1


def _wait_played(page: Any) -> None:
    """Wait for the whole episode, pause, go to step 0."""
    expect = _expect()
    expect(page.locator("#player")).to_have_attribute("data-ended", "true", timeout=WAIT_MS)
    if page.locator("#pl-play").inner_text() == "Pause":
        page.click("#pl-play")
    expect(page.locator("#pl-play")).to_have_text("Play")
    page.locator("#pl-time").press("Home")
    expect(page.locator("#player")).to_have_attribute("data-t", "0")


def test_a_live_particle_episode_renders_frame_by_frame(open_page: Any, shots: Path) -> None:
    page = open_page(f"episodes?{EPISODE}&infer=1&methods=aail")
    _wait_played(page)
    frames = []
    for _ in range(25):
        frames.append(page.evaluate(READ_LANES))
        page.click("#pl-step")
    assert [f["t"] for f in frames] == list(range(25))
    for frame in frames:
        (lane,) = frame["lanes"]
        assert len(lane["agents"]) == 2 and len(lane["bars"]) == 2 and len(lane["beliefs"]) == 1
        assert all(abs(total - 1.0) < 1e-6 for total in lane["bars"] + lane["beliefs"])
    positions = [frame["lanes"][0]["agents"] for frame in frames]
    moved = sum(before != after for before, after in itertools.pairwise(positions))
    assert moved >= 20  # agent positions change from frame to frame
    screenshot(page, shots, "episode-particle")


def test_sl_and_aail_side_by_side_differ_and_a_link_reproduces_it(
    open_page: Any, shots: Path
) -> None:
    page = open_page(f"episodes?{EPISODE}&methods=sl,aail")
    _wait_played(page)
    frames = []
    for _ in range(30):
        frames.append(page.evaluate(READ_LANES))
        page.click("#pl-step")
    sl, aail = ([f["lanes"][k]["agents"] for f in frames] for k in (0, 1))
    assert [lane["method"] for lane in frames[0]["lanes"]] == ["sl", "aail"]
    assert sl[0] == aail[0]  # the same start, the same random numbers
    assert sl != aail  # different trajectories
    assert frames[-1]["lanes"][0]["returns"] != frames[-1]["lanes"][1]["returns"]
    screenshot(page, shots, "episode-sl-vs-aail")
    link = page.locator("#pl-link").get_attribute("href")
    again = open_page(link.split("#/", 1)[1])
    _wait_played(again)
    for _ in range(12):
        again.click("#pl-step")
    assert again.evaluate(READ_LANES)["lanes"] == frames[12]["lanes"]


def test_a_kitchen_episode_renders(open_page: Any, shots: Path) -> None:
    page = open_page(f"episodes?{KITCHEN}&methods=sl,aail")
    _wait_played(page)
    page.click("#pl-step")
    state = page.evaluate(READ_LANES)
    for lane in state["lanes"]:
        assert len(lane["agents"]) == 2 and all(abs(t - 1.0) < 1e-6 for t in lane["bars"])
    cells = page.locator(".lane").first.locator(".layer-static rect")
    _expect()(cells).to_have_count(55)  # the 11 × 5 kitchen of paper Fig. 8
    assert page.locator(".lane").first.locator(".layer-objects circle").count() > 0
    screenshot(page, shots, "episode-kitchen")


@pytest.mark.slow
def test_a_job_is_submitted_followed_and_cancelled(open_page: Any, shots: Path) -> None:
    expect = _expect()
    page = open_page("jobs", token=ADMIN)
    page.select_option("#job-env", "particle")
    page.fill("#job-goals", "e4")
    page.fill("#job-steps", "50000")
    page.click("#job-form button[type=submit]")
    expect(page.locator("#job-status")).to_have_text("running", timeout=WAIT_MS)
    expect(page.locator("#job-progress-text")).to_contain_text("steps", timeout=90_000)
    assert float(page.locator("#job-progress").get_attribute("value") or 0) > 0
    expect(page.locator("#job-log")).to_contain_text("task e4..e4:")
    screenshot(page, shots, "jobs")
    page.get_by_role("button", name="Cancel job").click()
    expect(page.locator("#job-status")).to_have_text("cancelled", timeout=WAIT_MS)
