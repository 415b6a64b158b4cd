from collections.abc import Iterable as _Iterable
from collections.abc import Mapping as _Mapping
from typing import ClassVar as _ClassVar

from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from google.protobuf.internal import containers as _containers
from google.protobuf.internal import enum_type_wrapper as _enum_type_wrapper

DESCRIPTOR: _descriptor.FileDescriptor

class BatchFormat(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
    __slots__ = ()
    BATCH_FORMAT_ROWS: _ClassVar[BatchFormat]
    BATCH_FORMAT_COLUMNS: _ClassVar[BatchFormat]

BATCH_FORMAT_ROWS: BatchFormat
BATCH_FORMAT_COLUMNS: BatchFormat

class Vector(_message.Message):
    __slots__ = ("values",)
    VALUES_FIELD_NUMBER: _ClassVar[int]
    values: _containers.RepeatedScalarFieldContainer[float]
    def __init__(self, values: _Iterable[float] | None = ...) -> None: ...

class State(_message.Message):
    __slots__ = ("agents",)
    AGENTS_FIELD_NUMBER: _ClassVar[int]
    agents: _containers.RepeatedCompositeFieldContainer[Vector]
    def __init__(self, agents: _Iterable[Vector | _Mapping] | None = ...) -> None: ...

class PartnerSpec(_message.Message):
    __slots__ = ("goal", "goal_probs", "index", "infer")
    class GoalProbsEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: float
        def __init__(self, key: str | None = ..., value: float | None = ...) -> None: ...

    INDEX_FIELD_NUMBER: _ClassVar[int]
    GOAL_FIELD_NUMBER: _ClassVar[int]
    GOAL_PROBS_FIELD_NUMBER: _ClassVar[int]
    INFER_FIELD_NUMBER: _ClassVar[int]
    index: int
    goal: str
    goal_probs: _containers.ScalarMap[str, float]
    infer: bool
    def __init__(
        self,
        index: int | None = ...,
        goal: str | None = ...,
        goal_probs: _Mapping[str, float] | None = ...,
        infer: bool | None = ...,
    ) -> None: ...

class BeliefSettings(_message.Message):
    __slots__ = ("blend_mass", "blend_max_goals", "floor", "forgetting", "temperature")
    FORGETTING_FIELD_NUMBER: _ClassVar[int]
    FLOOR_FIELD_NUMBER: _ClassVar[int]
    TEMPERATURE_FIELD_NUMBER: _ClassVar[int]
    BLEND_MASS_FIELD_NUMBER: _ClassVar[int]
    BLEND_MAX_GOALS_FIELD_NUMBER: _ClassVar[int]
    forgetting: float
    floor: float
    temperature: float
    blend_mass: float
    blend_max_goals: int
    def __init__(
        self,
        forgetting: float | None = ...,
        floor: float | None = ...,
        temperature: float | None = ...,
        blend_mass: float | None = ...,
        blend_max_goals: int | None = ...,
    ) -> None: ...

class ActRequest(_message.Message):
    __slots__ = (
        "alias",
        "ego_goal",
        "ego_index",
        "env",
        "method",
        "observation",
        "partners",
        "regret_bound",
        "seed",
        "state",
        "temperature",
        "versions",
    )
    class VersionsEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: int
        def __init__(self, key: str | None = ..., value: int | None = ...) -> None: ...

    ENV_FIELD_NUMBER: _ClassVar[int]
    EGO_GOAL_FIELD_NUMBER: _ClassVar[int]
    OBSERVATION_FIELD_NUMBER: _ClassVar[int]
    STATE_FIELD_NUMBER: _ClassVar[int]
    EGO_INDEX_FIELD_NUMBER: _ClassVar[int]
    PARTNERS_FIELD_NUMBER: _ClassVar[int]
    METHOD_FIELD_NUMBER: _ClassVar[int]
    TEMPERATURE_FIELD_NUMBER: _ClassVar[int]
    SEED_FIELD_NUMBER: _ClassVar[int]
    ALIAS_FIELD_NUMBER: _ClassVar[int]
    VERSIONS_FIELD_NUMBER: _ClassVar[int]
    REGRET_BOUND_FIELD_NUMBER: _ClassVar[int]
    env: str
    ego_goal: str
    observation: _containers.RepeatedScalarFieldContainer[float]
    state: State
    ego_index: int
    partners: _containers.RepeatedCompositeFieldContainer[PartnerSpec]
    method: str
    temperature: float
    seed: int
    alias: str
    versions: _containers.ScalarMap[str, int]
    regret_bound: float
    def __init__(
        self,
        env: str | None = ...,
        ego_goal: str | None = ...,
        observation: _Iterable[float] | None = ...,
        state: State | _Mapping | None = ...,
        ego_index: int | None = ...,
        partners: _Iterable[PartnerSpec | _Mapping] | None = ...,
        method: str | None = ...,
        temperature: float | None = ...,
        seed: int | None = ...,
        alias: str | None = ...,
        versions: _Mapping[str, int] | None = ...,
        regret_bound: float | None = ...,
    ) -> None: ...

class Matrix(_message.Message):
    __slots__ = ("cols", "rows", "values")
    ROWS_FIELD_NUMBER: _ClassVar[int]
    COLS_FIELD_NUMBER: _ClassVar[int]
    VALUES_FIELD_NUMBER: _ClassVar[int]
    rows: int
    cols: int
    values: _containers.RepeatedScalarFieldContainer[float]
    def __init__(
        self, rows: int | None = ..., cols: int | None = ..., values: _Iterable[float] | None = ...
    ) -> None: ...

class ActBatchRequest(_message.Message):
    __slots__ = (
        "alias",
        "ego_goal",
        "ego_index",
        "env",
        "format",
        "method",
        "observation_matrix",
        "observations",
        "partners",
        "regret_bound",
        "seed",
        "states",
        "temperature",
        "versions",
    )
    class VersionsEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: int
        def __init__(self, key: str | None = ..., value: int | None = ...) -> None: ...

    ENV_FIELD_NUMBER: _ClassVar[int]
    EGO_GOAL_FIELD_NUMBER: _ClassVar[int]
    OBSERVATIONS_FIELD_NUMBER: _ClassVar[int]
    STATES_FIELD_NUMBER: _ClassVar[int]
    EGO_INDEX_FIELD_NUMBER: _ClassVar[int]
    PARTNERS_FIELD_NUMBER: _ClassVar[int]
    METHOD_FIELD_NUMBER: _ClassVar[int]
    TEMPERATURE_FIELD_NUMBER: _ClassVar[int]
    SEED_FIELD_NUMBER: _ClassVar[int]
    ALIAS_FIELD_NUMBER: _ClassVar[int]
    VERSIONS_FIELD_NUMBER: _ClassVar[int]
    OBSERVATION_MATRIX_FIELD_NUMBER: _ClassVar[int]
    FORMAT_FIELD_NUMBER: _ClassVar[int]
    REGRET_BOUND_FIELD_NUMBER: _ClassVar[int]
    env: str
    ego_goal: str
    observations: _containers.RepeatedCompositeFieldContainer[Vector]
    states: _containers.RepeatedCompositeFieldContainer[State]
    ego_index: int
    partners: _containers.RepeatedCompositeFieldContainer[PartnerSpec]
    method: str
    temperature: float
    seed: int
    alias: str
    versions: _containers.ScalarMap[str, int]
    observation_matrix: Matrix
    format: BatchFormat
    regret_bound: float
    def __init__(
        self,
        env: str | None = ...,
        ego_goal: str | None = ...,
        observations: _Iterable[Vector | _Mapping] | None = ...,
        states: _Iterable[State | _Mapping] | None = ...,
        ego_index: int | None = ...,
        partners: _Iterable[PartnerSpec | _Mapping] | None = ...,
        method: str | None = ...,
        temperature: float | None = ...,
        seed: int | None = ...,
        alias: str | None = ...,
        versions: _Mapping[str, int] | None = ...,
        observation_matrix: Matrix | _Mapping | None = ...,
        format: BatchFormat | str | None = ...,
        regret_bound: float | None = ...,
    ) -> None: ...

class EpisodeSettings(_message.Message):
    __slots__ = (
        "alias",
        "belief",
        "ego_goal",
        "env",
        "method",
        "partners",
        "regret_bound",
        "seed",
        "temperature",
        "versions",
    )
    class VersionsEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: int
        def __init__(self, key: str | None = ..., value: int | None = ...) -> None: ...

    ENV_FIELD_NUMBER: _ClassVar[int]
    EGO_GOAL_FIELD_NUMBER: _ClassVar[int]
    PARTNERS_FIELD_NUMBER: _ClassVar[int]
    METHOD_FIELD_NUMBER: _ClassVar[int]
    TEMPERATURE_FIELD_NUMBER: _ClassVar[int]
    SEED_FIELD_NUMBER: _ClassVar[int]
    ALIAS_FIELD_NUMBER: _ClassVar[int]
    VERSIONS_FIELD_NUMBER: _ClassVar[int]
    BELIEF_FIELD_NUMBER: _ClassVar[int]
    REGRET_BOUND_FIELD_NUMBER: _ClassVar[int]
    env: str
    ego_goal: str
    partners: _containers.RepeatedCompositeFieldContainer[PartnerSpec]
    method: str
    temperature: float
    seed: int
    alias: str
    versions: _containers.ScalarMap[str, int]
    belief: BeliefSettings
    regret_bound: float
    def __init__(
        self,
        env: str | None = ...,
        ego_goal: str | None = ...,
        partners: _Iterable[PartnerSpec | _Mapping] | None = ...,
        method: str | None = ...,
        temperature: float | None = ...,
        seed: int | None = ...,
        alias: str | None = ...,
        versions: _Mapping[str, int] | None = ...,
        belief: BeliefSettings | _Mapping | None = ...,
        regret_bound: float | None = ...,
    ) -> None: ...

class ObservedAction(_message.Message):
    __slots__ = ("action", "index")
    INDEX_FIELD_NUMBER: _ClassVar[int]
    ACTION_FIELD_NUMBER: _ClassVar[int]
    index: int
    action: int
    def __init__(self, index: int | None = ..., action: int | None = ...) -> None: ...

class EpisodeStep(_message.Message):
    __slots__ = ("ego_index", "observation", "observed", "settings", "state")
    SETTINGS_FIELD_NUMBER: _ClassVar[int]
    OBSERVATION_FIELD_NUMBER: _ClassVar[int]
    STATE_FIELD_NUMBER: _ClassVar[int]
    EGO_INDEX_FIELD_NUMBER: _ClassVar[int]
    OBSERVED_FIELD_NUMBER: _ClassVar[int]
    settings: EpisodeSettings
    observation: _containers.RepeatedScalarFieldContainer[float]
    state: State
    ego_index: int
    observed: _containers.RepeatedCompositeFieldContainer[ObservedAction]
    def __init__(
        self,
        settings: EpisodeSettings | _Mapping | None = ...,
        observation: _Iterable[float] | None = ...,
        state: State | _Mapping | None = ...,
        ego_index: int | None = ...,
        observed: _Iterable[ObservedAction | _Mapping] | None = ...,
    ) -> None: ...

class PartnerWeight(_message.Message):
    __slots__ = ("index", "weight")
    INDEX_FIELD_NUMBER: _ClassVar[int]
    WEIGHT_FIELD_NUMBER: _ClassVar[int]
    index: int
    weight: float
    def __init__(self, index: int | None = ..., weight: float | None = ...) -> None: ...

class Diagnostics(_message.Message):
    __slots__ = ("partner_weights", "task_entropy", "task_weight")
    TASK_ENTROPY_FIELD_NUMBER: _ClassVar[int]
    TASK_WEIGHT_FIELD_NUMBER: _ClassVar[int]
    PARTNER_WEIGHTS_FIELD_NUMBER: _ClassVar[int]
    task_entropy: float
    task_weight: float
    partner_weights: _containers.RepeatedCompositeFieldContainer[PartnerWeight]
    def __init__(
        self,
        task_entropy: float | None = ...,
        task_weight: float | None = ...,
        partner_weights: _Iterable[PartnerWeight | _Mapping] | None = ...,
    ) -> None: ...

class ModelUsed(_message.Message):
    __slots__ = ("goal", "name", "partner_index", "role", "sha256", "version")
    ROLE_FIELD_NUMBER: _ClassVar[int]
    NAME_FIELD_NUMBER: _ClassVar[int]
    VERSION_FIELD_NUMBER: _ClassVar[int]
    SHA256_FIELD_NUMBER: _ClassVar[int]
    PARTNER_INDEX_FIELD_NUMBER: _ClassVar[int]
    GOAL_FIELD_NUMBER: _ClassVar[int]
    role: str
    name: str
    version: int
    sha256: str
    partner_index: int
    goal: str
    def __init__(
        self,
        role: str | None = ...,
        name: str | None = ...,
        version: int | None = ...,
        sha256: str | None = ...,
        partner_index: int | None = ...,
        goal: str | None = ...,
    ) -> None: ...

class GoalProb(_message.Message):
    __slots__ = ("goal", "prob")
    GOAL_FIELD_NUMBER: _ClassVar[int]
    PROB_FIELD_NUMBER: _ClassVar[int]
    goal: str
    prob: float
    def __init__(self, goal: str | None = ..., prob: float | None = ...) -> None: ...

class PartnerBelief(_message.Message):
    __slots__ = ("entropy", "index", "observed_action", "top", "updates")
    INDEX_FIELD_NUMBER: _ClassVar[int]
    TOP_FIELD_NUMBER: _ClassVar[int]
    ENTROPY_FIELD_NUMBER: _ClassVar[int]
    OBSERVED_ACTION_FIELD_NUMBER: _ClassVar[int]
    UPDATES_FIELD_NUMBER: _ClassVar[int]
    index: int
    top: _containers.RepeatedCompositeFieldContainer[GoalProb]
    entropy: float
    observed_action: int
    updates: int
    def __init__(
        self,
        index: int | None = ...,
        top: _Iterable[GoalProb | _Mapping] | None = ...,
        entropy: float | None = ...,
        observed_action: int | None = ...,
        updates: int | None = ...,
    ) -> None: ...

class ActResponse(_message.Message):
    __slots__ = (
        "action",
        "action_meaning",
        "beliefs",
        "diagnostics",
        "greedy_action",
        "method",
        "models",
        "probs",
    )
    PROBS_FIELD_NUMBER: _ClassVar[int]
    ACTION_FIELD_NUMBER: _ClassVar[int]
    GREEDY_ACTION_FIELD_NUMBER: _ClassVar[int]
    ACTION_MEANING_FIELD_NUMBER: _ClassVar[int]
    METHOD_FIELD_NUMBER: _ClassVar[int]
    DIAGNOSTICS_FIELD_NUMBER: _ClassVar[int]
    MODELS_FIELD_NUMBER: _ClassVar[int]
    BELIEFS_FIELD_NUMBER: _ClassVar[int]
    probs: _containers.RepeatedScalarFieldContainer[float]
    action: int
    greedy_action: int
    action_meaning: str
    method: str
    diagnostics: Diagnostics
    models: _containers.RepeatedCompositeFieldContainer[ModelUsed]
    beliefs: _containers.RepeatedCompositeFieldContainer[PartnerBelief]
    def __init__(
        self,
        probs: _Iterable[float] | None = ...,
        action: int | None = ...,
        greedy_action: int | None = ...,
        action_meaning: str | None = ...,
        method: str | None = ...,
        diagnostics: Diagnostics | _Mapping | None = ...,
        models: _Iterable[ModelUsed | _Mapping] | None = ...,
        beliefs: _Iterable[PartnerBelief | _Mapping] | None = ...,
    ) -> None: ...

class ActColumns(_message.Message):
    __slots__ = (
        "action_meanings",
        "actions",
        "greedy_actions",
        "method",
        "models",
        "n_actions",
        "partner_indices",
        "partner_weights",
        "probs",
        "rows",
        "task_entropies",
        "task_weights",
    )
    METHOD_FIELD_NUMBER: _ClassVar[int]
    MODELS_FIELD_NUMBER: _ClassVar[int]
    ROWS_FIELD_NUMBER: _ClassVar[int]
    N_ACTIONS_FIELD_NUMBER: _ClassVar[int]
    PROBS_FIELD_NUMBER: _ClassVar[int]
    ACTIONS_FIELD_NUMBER: _ClassVar[int]
    GREEDY_ACTIONS_FIELD_NUMBER: _ClassVar[int]
    ACTION_MEANINGS_FIELD_NUMBER: _ClassVar[int]
    TASK_ENTROPIES_FIELD_NUMBER: _ClassVar[int]
    TASK_WEIGHTS_FIELD_NUMBER: _ClassVar[int]
    PARTNER_INDICES_FIELD_NUMBER: _ClassVar[int]
    PARTNER_WEIGHTS_FIELD_NUMBER: _ClassVar[int]
    method: str
    models: _containers.RepeatedCompositeFieldContainer[ModelUsed]
    rows: int
    n_actions: int
    probs: _containers.RepeatedScalarFieldContainer[float]
    actions: _containers.RepeatedScalarFieldContainer[int]
    greedy_actions: _containers.RepeatedScalarFieldContainer[int]
    action_meanings: _containers.RepeatedScalarFieldContainer[str]
    task_entropies: _containers.RepeatedScalarFieldContainer[float]
    task_weights: _containers.RepeatedScalarFieldContainer[float]
    partner_indices: _containers.RepeatedScalarFieldContainer[int]
    partner_weights: _containers.RepeatedScalarFieldContainer[float]
    def __init__(
        self,
        method: str | None = ...,
        models: _Iterable[ModelUsed | _Mapping] | None = ...,
        rows: int | None = ...,
        n_actions: int | None = ...,
        probs: _Iterable[float] | None = ...,
        actions: _Iterable[int] | None = ...,
        greedy_actions: _Iterable[int] | None = ...,
        action_meanings: _Iterable[str] | None = ...,
        task_entropies: _Iterable[float] | None = ...,
        task_weights: _Iterable[float] | None = ...,
        partner_indices: _Iterable[int] | None = ...,
        partner_weights: _Iterable[float] | None = ...,
    ) -> None: ...

class ActBatchResponse(_message.Message):
    __slots__ = ("columns", "results")
    RESULTS_FIELD_NUMBER: _ClassVar[int]
    COLUMNS_FIELD_NUMBER: _ClassVar[int]
    results: _containers.RepeatedCompositeFieldContainer[ActResponse]
    columns: ActColumns
    def __init__(
        self,
        results: _Iterable[ActResponse | _Mapping] | None = ...,
        columns: ActColumns | _Mapping | None = ...,
    ) -> None: ...

class ListEnvsRequest(_message.Message):
    __slots__ = ()
    def __init__(self) -> None: ...

class ObservationLayout(_message.Message):
    __slots__ = ("features", "n_agents", "obs_dim")
    N_AGENTS_FIELD_NUMBER: _ClassVar[int]
    OBS_DIM_FIELD_NUMBER: _ClassVar[int]
    FEATURES_FIELD_NUMBER: _ClassVar[int]
    n_agents: int
    obs_dim: int
    features: _containers.RepeatedScalarFieldContainer[str]
    def __init__(
        self,
        n_agents: int | None = ...,
        obs_dim: int | None = ...,
        features: _Iterable[str] | None = ...,
    ) -> None: ...

class EnvInfo(_message.Message):
    __slots__ = (
        "action_meanings",
        "goals",
        "max_agents",
        "methods",
        "name",
        "observation_layouts",
        "pair_obs_dim",
        "state_layout",
    )
    NAME_FIELD_NUMBER: _ClassVar[int]
    GOALS_FIELD_NUMBER: _ClassVar[int]
    ACTION_MEANINGS_FIELD_NUMBER: _ClassVar[int]
    MAX_AGENTS_FIELD_NUMBER: _ClassVar[int]
    OBSERVATION_LAYOUTS_FIELD_NUMBER: _ClassVar[int]
    STATE_LAYOUT_FIELD_NUMBER: _ClassVar[int]
    PAIR_OBS_DIM_FIELD_NUMBER: _ClassVar[int]
    METHODS_FIELD_NUMBER: _ClassVar[int]
    name: str
    goals: _containers.RepeatedScalarFieldContainer[str]
    action_meanings: _containers.RepeatedScalarFieldContainer[str]
    max_agents: int
    observation_layouts: _containers.RepeatedCompositeFieldContainer[ObservationLayout]
    state_layout: _containers.RepeatedScalarFieldContainer[str]
    pair_obs_dim: int
    methods: _containers.RepeatedScalarFieldContainer[str]
    def __init__(
        self,
        name: str | None = ...,
        goals: _Iterable[str] | None = ...,
        action_meanings: _Iterable[str] | None = ...,
        max_agents: int | None = ...,
        observation_layouts: _Iterable[ObservationLayout | _Mapping] | None = ...,
        state_layout: _Iterable[str] | None = ...,
        pair_obs_dim: int | None = ...,
        methods: _Iterable[str] | None = ...,
    ) -> None: ...

class ListEnvsResponse(_message.Message):
    __slots__ = ("envs",)
    ENVS_FIELD_NUMBER: _ClassVar[int]
    envs: _containers.RepeatedCompositeFieldContainer[EnvInfo]
    def __init__(self, envs: _Iterable[EnvInfo | _Mapping] | None = ...) -> None: ...
