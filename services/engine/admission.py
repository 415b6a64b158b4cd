"""What the registry admits: only networks the engine can serve.

| check                       | when                       | refusal                              |
|-----------------------------|----------------------------|--------------------------------------|
| `refuse_unservable_upload`  | before a version registers | `InvalidArtifact` (422, `weights`)   |
| `refuse_unservable_version` | before an alias moves      | `Conflict` (409, `version`)          |

Both run the engine's own load and forward (`services.engine.networks.probe_net`: the path of a
request, on probe observations) rather than a copy of it, so whatever the engine could not answer
with finite Q-values never registers and never becomes what an alias such as `production` serves:
the alias stays on the last good version. The REST registry and `coexist models` (straight
through the store) both call them.
"""

from __future__ import annotations

from typing import Any

from model_store.errors import Conflict, InvalidArtifact, ModelStoreError
from model_store.naming import validate_alias
from model_store.store import ModelStore
from services.engine.networks import UnservableNetwork, check_servable, load_net


def refuse_unservable_upload(spec: Any, weights: bytes) -> None:
    """InvalidArtifact (422, `weights`) for an upload that parses but that the engine could not
    serve; a malformed one is left to the store's own checks, which name the bad part."""
    try:
        check_servable(spec, weights)
    except UnservableNetwork as exc:
        raise InvalidArtifact(f"weights: cannot be served: {exc}", field="weights") from None
    except (ValueError, TypeError, KeyError):
        pass  # malformed: `register_version` refuses it, naming the part


def refuse_unservable_version(store: ModelStore, name: str, version: int, alias: str) -> None:
    """Conflict (409, `version`) unless the version loads and passes the engine's probe
    (`load_net`): moving `alias` there would make every request that uses it fail."""
    validate_alias(alias)  # a bad alias is the request's first fault, as in `set_alias`
    meta = store.get_version(name, version)  # 404 for a version that does not exist
    try:
        load_net(store, meta)
    except ModelStoreError:
        raise  # the store's own answer (503 while it is down, 502 on a checksum mismatch)
    except (ValueError, TypeError, KeyError) as exc:
        raise Conflict(
            f"version: {meta.ref} cannot be served ({exc}); {name}@{alias} was not moved",
            field="version",
        ) from None
