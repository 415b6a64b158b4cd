"""model_store: the registry of every network coexist trains (task, impact, joint).

Layers (ORM rows never leave `model_store.sql`):

    entities.py      frozen dataclasses: RegisteredModel, ModelVersion, Lineage, Event, Page
    errors.py        domain errors (NotFound, AlreadyExists, InvalidArtifact, ...)
    store.py         the abstract ModelStore interface and its semantics
    sql/             SqlModelStore on SQLite (default) or PostgreSQL; Alembic in migrations/
    naming.py        model names, aliases and refs (`name@alias`, `name/3`)
    checks.py        what every backend checks before it writes (a new model, a registration)
    artifacts.py     the checks of a version's spec, weights and lineage
    defaults.py      default_store_url(), open_store()

Typical use:

    store = open_store(create=True)  # a reader passes no `create`: a missing file is an error
    store.create_model(task_model_name("particle", "a3"), env="particle", kind="task",
                       goals=["a3"], obs_dim=8, n_actions=5, exist_ok=True)
    mv = store.register_version("particle/task/a3", spec=spec, weights=blob, lineage=lineage)
    blob = store.load_weights(mv.name, mv.version)    # sha256 verified
"""

from model_store.defaults import default_store_url, open_store
from model_store.entities import Event, Lineage, ModelVersion, Page, RegisteredModel
from model_store.errors import (
    AlreadyExists,
    ArtifactTooLarge,
    ChecksumMismatch,
    Conflict,
    InvalidArgument,
    InvalidArtifact,
    ModelStoreError,
    NotFound,
    SchemaTooNew,
    StoreUnavailable,
)
from model_store.naming import (
    impact_model_name,
    joint_model_name,
    parse_ref,
    task_model_name,
)
from model_store.store import ModelStore

__all__ = [
    "AlreadyExists",
    "ArtifactTooLarge",
    "ChecksumMismatch",
    "Conflict",
    "Event",
    "InvalidArgument",
    "InvalidArtifact",
    "Lineage",
    "ModelStore",
    "ModelStoreError",
    "ModelVersion",
    "NotFound",
    "Page",
    "RegisteredModel",
    "SchemaTooNew",
    "StoreUnavailable",
    "default_store_url",
    "impact_model_name",
    "joint_model_name",
    "open_store",
    "parse_ref",
    "task_model_name",
]
