"""Load the served models before the first request, so `/readyz` means "ready to answer".

The engine loads networks lazily (first use); a replica behind a load balancer should not take
traffic until its production networks are loaded and their sha256 verified. At start-up every
model with a `production` version is resolved and loaded, up to the engine's cache size.
"""

from __future__ import annotations

import logging

from model_store.errors import ModelStoreError
from services.engine import EngineError, InferenceEngine

log = logging.getLogger("coexist.server")


def warm_up(engine: InferenceEngine, alias: str = "production", limit: int = 256) -> int:
    """Resolve and load up to `limit` models that have `alias`; returns how many loaded."""
    loaded = 0
    token: str | None = None
    try:
        while loaded < limit:
            page = engine.store.list_models(page_size=100, page_token=token)
            for model in page.items:
                if alias not in model.aliases or loaded >= limit:
                    continue
                try:
                    version = engine.cache.resolve(model.name, alias, {}, "warm-up", "warm-up")
                    engine.cache.net(version)
                    loaded += 1
                except (EngineError, ModelStoreError, ValueError) as exc:
                    log.warning("warm-up: could not load %s@%s: %s", model.name, alias, exc)
            token = page.next_page_token
            if token is None:
                break
    except ModelStoreError as exc:
        log.warning("warm-up: model store not reachable: %s", exc)
    log.info("warm-up: %d %s models loaded", loaded, alias)
    return loaded
