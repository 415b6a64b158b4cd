"""`ModelCache`: everything the engine keeps from the store, and hot reload.

| table        | key                          | value                  | bound                   |
|--------------|------------------------------|------------------------|-------------------------|
| resolutions  | (name, alias)                | `ModelVersion`         | 4096, swapped on reload |
| pinned       | (name, version)              | `ModelVersion`         | 4096                    |
| nets         | (name, version)              | `LoadedNet`            | `cache_size`            |
| stacks       | ((name, version), ...)       | `StackedGroup`         | `stack_cache_size`      |
| fixed sets   | (id of a needs tuple, alias) | versions + stack key   | 1024, void after reload |

Versions are immutable, so only `name@alias` resolutions can go stale. `refresh()` reads the
store's change token *first* (a change made while it runs shows up next time); when the token
moved, every cached alias is resolved again, new versions are loaded and verified, and only then
is the new resolution table swapped in by one assignment. A request that missed the table while a
refresh ran writes its entry only if the table it read is still current, so a stale version can
never land in the new table. Requests in flight keep the objects they hold. Locks guard dict
operations only, never a load or a forward.

Fixed sets (`resolve_group`): a caller that asks again and again for the same tuple of names (the
engine's cached request plans; goal inference's task network of every goal, 35 in the particle
world) gets the versions and the stacked group in one look-up instead of one per name. An
entry remembers the resolution table it was read from and counts
only while that table is current, so a reload (which always swaps the table when the store's
change token moved) invalidates every fixed set at once: hot reload works as for single names.
An entry holds no group, only its stack key: the group comes from the stack LRU, whose bound and
order stay as they were. Counters are the per-name path's; the resolutions' LRU order is not
refreshed by a fixed-set hit.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import cast

from envs.base import Domain
from model_store.entities import ModelVersion
from model_store.errors import InvalidArgument, ModelStoreError, NotFound, StoreUnavailable
from model_store.store import ModelStore
from services.engine.errors import ModelNotFound, ModelUnavailable
from services.engine.messages import EngineStats, Member
from services.engine.networks import LoadedNet, LruCache, StackedGroup, build_group, load_net

log = logging.getLogger(__name__)

MAX_RESOLUTIONS = 4096
MAX_FIXED_SETS = 1024  # fixed name tuples remembered (the table is cleared when full)

Needs = tuple[tuple[str, str, str], ...]  # (model name, field to blame, why it is needed)


@dataclass(frozen=True, eq=False)
class _FixedSet:
    needs: Needs  # held so that its id, the key, is not reused while the entry lives
    members: Sequence[Member]
    table: object  # the resolution table the versions were read from
    versions: list[ModelVersion]
    stack_key: tuple[tuple[str, int], ...]


class ModelCache:
    """Resolutions, loaded networks and stacked groups of one store (module docstring)."""

    def __init__(
        self, store: ModelStore, stats: EngineStats, *, cache_size: int, stack_cache_size: int
    ) -> None:
        self.store = store
        self.stats = stats
        self._nets: LruCache[tuple[str, int], LoadedNet] = LruCache(cache_size)
        self._stacks: LruCache[tuple[tuple[str, int], ...], StackedGroup] = LruCache(
            stack_cache_size
        )
        self._resolved: LruCache[tuple[str, str], ModelVersion] = LruCache(MAX_RESOLUTIONS)
        self._pinned: LruCache[tuple[str, int], ModelVersion] = LruCache(MAX_RESOLUTIONS)
        self._fixed: dict[tuple[int, str], _FixedSet] = {}
        self._swap_lock = threading.Lock()
        self._refresh_lock = threading.Lock()
        self.last_token: str | None = None
        # the store's generation: moves whenever `refresh()` sees a new change token (what the
        # engine derived from the store before then may be stale: `planning.PlanCache`)
        self.generation = 0
        try:
            self.last_token = store.change_token()
        except ModelStoreError as exc:  # the store may come up later; refresh() will retry
            log.warning("model store not reachable at start: %s", exc)

    # --- resolve, load, stack --------------------------------------------------------------
    def resolve(
        self, name: str, alias: str, pinned: Mapping[str, int], field: str, why: str
    ) -> ModelVersion:
        """The version of `name` pinned in `pinned`, else under `alias`; `ModelNotFound` names
        `field` (or `versions[name]` for a pinned one) and says `why` the network is needed."""
        version = pinned.get(name) if pinned else None
        if version is not None:
            found = self._pinned.get((name, version))
            if found is None:
                found = self._from_store(name, f"{name}/{version}", f"versions[{name}]", why)
                self._pinned.put((name, version), found)
            return found
        table = self._resolved
        found = table.get((name, alias))
        if found is not None:
            self.stats.resolve_hits += 1
            return found
        self.stats.resolve_misses += 1
        found = self._from_store(name, f"{name}@{alias}", field, why)
        with self._swap_lock:  # a refresh swapped the table meanwhile: drop the entry
            if self._resolved is table:
                table.put((name, alias), found)
        return found

    def resolve_all(
        self, needs: Sequence[tuple[str, str, str]], alias: str, pinned: Mapping[str, int]
    ) -> list[ModelVersion]:
        """`resolve` of each (name, field, why) in order. When every one is a cached alias
        resolution, one table look-up serves them all (same counters and LRU order)."""
        if not pinned:
            found = self._resolved.get_all([(name, alias) for name, _, _ in needs])
            if None not in found:
                self.stats.resolve_hits += len(found)
                return cast(list[ModelVersion], found)  # no None in it
        return [self.resolve(name, alias, pinned, field, why) for name, field, why in needs]

    def resolve_group(
        self,
        needs: Needs,
        alias: str,
        pinned: Mapping[str, int],
        members: Sequence[Member],
        domain: Domain,
    ) -> tuple[list[ModelVersion], StackedGroup]:
        """`resolve_all(needs, ...)` then `group(...)` of the versions, in one look-up when the
        same `needs` tuple (the same object) came with `alias` before and no reload happened
        since (module docstring, "fixed sets"). Pinned versions take the per-name path. The
        versions list is shared between calls: read it, never change it."""
        if pinned:
            versions = self.resolve_all(needs, alias, pinned)
            return versions, self.group(versions, members, domain)
        entry = self._current_fixed(needs, alias, members)
        if entry is not None:
            self.stats.resolve_hits += len(needs)
            group = self._stacks.get(entry.stack_key)
            if group is None:  # evicted by other groups: stack it again
                return entry.versions, self.group(
                    entry.versions, members, domain, key=entry.stack_key
                )
            self.stats.stack_hits += 1
            return entry.versions, group
        table = self._resolved  # read before resolving: a swap meanwhile voids the entry
        versions = self.resolve_all(needs, alias, pinned)
        stack_key = tuple((v.name, v.version) for v in versions)
        group = self.group(versions, members, domain, key=stack_key)
        if len(self._fixed) >= MAX_FIXED_SETS:
            self._fixed.clear()
        self._fixed[(id(needs), alias)] = _FixedSet(needs, members, table, versions, stack_key)
        return versions, group

    def cached_group(
        self, needs: Needs, alias: str, members: Sequence[Member]
    ) -> StackedGroup | None:
        """`resolve_group(needs, alias, {}, members, ...)`'s group when that is a look-up (a
        current fixed set whose group is still stacked; counted as one), else None: nothing
        is resolved, loaded or stacked."""
        entry = self._current_fixed(needs, alias, members)
        group = None if entry is None else self._stacks.get(entry.stack_key)
        if group is not None:
            self.stats.resolve_hits += len(needs)
            self.stats.stack_hits += 1
        return group

    def _current_fixed(
        self, needs: Needs, alias: str, members: Sequence[Member]
    ) -> _FixedSet | None:
        """The fixed set of this `needs` tuple and `alias`, if it was read from the current
        resolution table (module docstring, "fixed sets")."""
        entry = self._fixed.get((id(needs), alias))
        if (
            entry is None
            or entry.needs is not needs
            or entry.members is not members
            or entry.table is not self._resolved
        ):
            return None
        return entry

    def _from_store(self, name: str, ref: str, field: str, why: str) -> ModelVersion:
        try:
            return self.store.resolve(ref)
        except (NotFound, InvalidArgument) as exc:
            raise ModelNotFound(name, ref, field=field, message=f"{why}: {exc}") from None
        except ModelStoreError as exc:
            raise ModelUnavailable(name, f"model store error resolving {ref!r}: {exc}") from None

    def net(self, version: ModelVersion) -> LoadedNet:
        """The loaded network of `version` (cached); store errors propagate."""
        key = (version.name, version.version)
        net = self._nets.get(key)
        if net is not None:
            self.stats.cache_hits += 1
            return net
        self.stats.cache_misses += 1
        try:
            net = load_net(self.store, version)  # the store verifies the sha256
        except (ModelStoreError, ValueError):
            self.stats.load_failures += 1
            raise
        self.stats.loads += 1
        self._nets.put(key, net)
        return net

    def group(
        self,
        versions: Sequence[ModelVersion],
        members: Sequence[Member],
        domain: Domain,
        *,
        key: tuple[tuple[str, int], ...] | None = None,
    ) -> StackedGroup:
        """The stacked group of `versions` (cached by their (name, version) tuple, `key` if
        the caller has it already)."""
        if key is None:
            key = tuple((v.name, v.version) for v in versions)
        group = self._stacks.get(key)
        if group is not None:
            self.stats.stack_hits += 1
            return group
        self.stats.stack_misses += 1
        nets = []
        for version, (role, _) in zip(versions, members, strict=True):
            try:
                net = self.net(version)
            except (ModelStoreError, ValueError) as exc:
                raise ModelUnavailable(version.name, f"cannot load {version.ref}: {exc}") from None
            pair_ok = role == "joint" or net.spec.obs_dim == domain.pair_obs_dim
            if net.spec.n_actions != domain.n_actions or not pair_ok:
                raise ModelUnavailable(
                    net.name,
                    f"{version.ref} has obs_dim {net.spec.obs_dim} and n_actions "
                    f"{net.spec.n_actions}; env {domain.name!r} needs n_actions "
                    f"{domain.n_actions} (and obs_dim {domain.pair_obs_dim} for task/impact)",
                )
            nets.append(net)
        group = build_group(nets)
        self._stacks.put(key, group)
        return group

    # --- hot reload ------------------------------------------------------------------------
    def refresh(self) -> bool:
        """Reload moved aliases if the store changed; True when a served alias moved. A store
        outage is logged and counted (False); the next call retries."""
        with self._refresh_lock:
            try:
                token = self.store.change_token()
                if token == self.last_token:
                    return False
                self.stats.refreshes += 1
                self.generation += 1
                moved, complete = self._reresolve()
            except ModelStoreError as exc:
                self.stats.refresh_errors += 1
                log.warning("hot reload: model store error, will retry: %s", exc)
                return False
            if complete:  # otherwise keep the old token: the next refresh tries again
                self.last_token = token
            return moved

    def _reresolve(self) -> tuple[bool, bool]:
        """Resolve every cached alias again and swap the table; (an alias moved, no failure)."""
        fresh: LruCache[tuple[str, str], ModelVersion] = LruCache(MAX_RESOLUTIONS)
        moved, complete = False, True
        for (name, alias), old in self._resolved.items():
            try:
                new = self.store.resolve(f"{name}@{alias}")
            except (NotFound, InvalidArgument):  # alias or model deleted: stop serving it
                log.info("hot reload: %s@%s is gone (was version %d)", name, alias, old.version)
                moved = True
                continue
            if (new.version, new.sha256) != (old.version, old.sha256):
                try:
                    self.net(new)  # load and verify *before* the swap
                except StoreUnavailable:
                    raise  # an outage: refresh() logs it and retries everything next time
                except (ModelStoreError, ValueError) as exc:  # a bad new version: keep the old
                    log.error("hot reload: keeping %s/%d: %s", name, old.version, exc)
                    fresh.put((name, alias), old)
                    complete = False
                    continue
                log.info("hot reload: %s@%s %d -> %d", name, alias, old.version, new.version)
                self.stats.reloads += 1
                moved = True
            fresh.put((name, alias), new)
        with self._swap_lock:
            self._resolved = fresh
        return moved, complete

    # --- what is served --------------------------------------------------------------------
    def versions_served(self) -> dict[str, int]:
        """ "name@alias" -> version for every alias resolved so far, sorted by key."""
        return dict(sorted((f"{n}@{a}", v.version) for (n, a), v in self._resolved.items()))

    def models_loaded(self) -> int:
        return len(self._nets)
