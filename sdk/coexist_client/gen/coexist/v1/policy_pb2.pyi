from google.protobuf.internal import containers as _containers
from google.protobuf.internal import enum_type_wrapper as _enum_type_wrapper
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

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
    def __init__(self, values: _Optional[_Iterable[float]] = ...) -> None: ...

class State(_message.Message):
    __slots__ = ("agents",)
    AGENTS_FIELD_NUMBER: _ClassVar[int]
    agents: _containers.RepeatedCompositeFieldContainer[Vector]
    def __init__(self, agents: _Optional[_Iterable[_Union[Vector, _Mapping]]] = ...) -> None: ...

class PartnerSpec(_message.Message):
    __slots__ = ("index", "goal", "goal_probs", "infer")
    class GoalProbsEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: float
        def __init__(self, key: _Optional[str] = ..., value: _Optional[float] = ...) -> None: ...
    INDEX_FIELD_NUMBER: _ClassVar[int]
    GOAL_FIELD_NUMBER: _ClassVar[int]
    GOAL_PROBS_FIELD_NUMBER: _ClassVar[int]
    INFER_FIELD_NUMBER: _ClassVar[int]
    index: int
    goal: str
    goal_probs: _containers.ScalarMap[str, float]
    infer: bool
    def __init__(self, index: _Optional[int] = ..., goal: _Optional[str] = ..., goal_probs: _Optional[_Mapping[str, float]] = ..., infer: _Optional[bool] = ...) -> None: ...

class BeliefSettings(_message.Message):
    __slots__ = ("forgetting", "floor", "temperature", "blend_mass", "blend_max_goals", "prune_below", "prune_error", "noise")
    FORGETTING_FIELD_NUMBER: _ClassVar[int]
    FLOOR_FIELD_NUMBER: _ClassVar[int]
    TEMPERATURE_FIELD_NUMBER: _ClassVar[int]
    BLEND_MASS_FIELD_NUMBER: _ClassVar[int]
    BLEND_MAX_GOALS_FIELD_NUMBER: _ClassVar[int]
    PRUNE_BELOW_FIELD_NUMBER: _ClassVar[int]
    PRUNE_ERROR_FIELD_NUMBER: _ClassVar[int]
    NOISE_FIELD_NUMBER: _ClassVar[int]
    forgetting: float
    floor: float
    temperature: float
    blend_mass: float
    blend_max_goals: int
    prune_below: float
    prune_error: float
    noise: float
    def __init__(self, forgetting: _Optional[float] = ..., floor: _Optional[float] = ..., temperature: _Optional[float] = ..., blend_mass: _Optional[float] = ..., blend_max_goals: _Optional[int] = ..., prune_below: _Optional[float] = ..., prune_error: _Optional[float] = ..., noise: _Optional[float] = ...) -> None: ...

class ActRequest(_message.Message):
    __slots__ = ("env", "ego_goal", "observation", "state", "ego_index", "partners", "method", "temperature", "seed", "alias", "versions", "regret_bound", "budget", "budget_spent", "budget_total", "budget_value")
    class VersionsEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: int
        def __init__(self, key: _Optional[str] = ..., value: _Optional[int] = ...) -> None: ...
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
    BUDGET_FIELD_NUMBER: _ClassVar[int]
    BUDGET_SPENT_FIELD_NUMBER: _ClassVar[int]
    BUDGET_TOTAL_FIELD_NUMBER: _ClassVar[int]
    BUDGET_VALUE_FIELD_NUMBER: _ClassVar[int]
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
    budget: float
    budget_spent: float
    budget_total: float
    budget_value: float
    def __init__(self, env: _Optional[str] = ..., ego_goal: _Optional[str] = ..., observation: _Optional[_Iterable[float]] = ..., state: _Optional[_Union[State, _Mapping]] = ..., ego_index: _Optional[int] = ..., partners: _Optional[_Iterable[_Union[PartnerSpec, _Mapping]]] = ..., method: _Optional[str] = ..., temperature: _Optional[float] = ..., seed: _Optional[int] = ..., alias: _Optional[str] = ..., versions: _Optional[_Mapping[str, int]] = ..., regret_bound: _Optional[float] = ..., budget: _Optional[float] = ..., budget_spent: _Optional[float] = ..., budget_total: _Optional[float] = ..., budget_value: _Optional[float] = ...) -> None: ...

class Matrix(_message.Message):
    __slots__ = ("rows", "cols", "values")
    ROWS_FIELD_NUMBER: _ClassVar[int]
    COLS_FIELD_NUMBER: _ClassVar[int]
    VALUES_FIELD_NUMBER: _ClassVar[int]
    rows: int
    cols: int
    values: _containers.RepeatedScalarFieldContainer[float]
    def __init__(self, rows: _Optional[int] = ..., cols: _Optional[int] = ..., values: _Optional[_Iterable[float]] = ...) -> None: ...

class ActBatchRequest(_message.Message):
    __slots__ = ("env", "ego_goal", "observations", "states", "ego_index", "partners", "method", "temperature", "seed", "alias", "versions", "observation_matrix", "format", "regret_bound", "budget", "budget_spent", "budget_total", "budget_value")
    class VersionsEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: int
        def __init__(self, key: _Optional[str] = ..., value: _Optional[int] = ...) -> None: ...
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
    BUDGET_FIELD_NUMBER: _ClassVar[int]
    BUDGET_SPENT_FIELD_NUMBER: _ClassVar[int]
    BUDGET_TOTAL_FIELD_NUMBER: _ClassVar[int]
    BUDGET_VALUE_FIELD_NUMBER: _ClassVar[int]
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
    budget: float
    budget_spent: _containers.RepeatedScalarFieldContainer[float]
    budget_total: _containers.RepeatedScalarFieldContainer[float]
    budget_value: _containers.RepeatedScalarFieldContainer[float]
    def __init__(self, env: _Optional[str] = ..., ego_goal: _Optional[str] = ..., observations: _Optional[_Iterable[_Union[Vector, _Mapping]]] = ..., states: _Optional[_Iterable[_Union[State, _Mapping]]] = ..., ego_index: _Optional[int] = ..., partners: _Optional[_Iterable[_Union[PartnerSpec, _Mapping]]] = ..., method: _Optional[str] = ..., temperature: _Optional[float] = ..., seed: _Optional[int] = ..., alias: _Optional[str] = ..., versions: _Optional[_Mapping[str, int]] = ..., observation_matrix: _Optional[_Union[Matrix, _Mapping]] = ..., format: _Optional[_Union[BatchFormat, str]] = ..., regret_bound: _Optional[float] = ..., budget: _Optional[float] = ..., budget_spent: _Optional[_Iterable[float]] = ..., budget_total: _Optional[_Iterable[float]] = ..., budget_value: _Optional[_Iterable[float]] = ...) -> None: ...

class EpisodeSettings(_message.Message):
    __slots__ = ("env", "ego_goal", "partners", "method", "temperature", "seed", "alias", "versions", "belief", "regret_bound", "budget")
    class VersionsEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: int
        def __init__(self, key: _Optional[str] = ..., value: _Optional[int] = ...) -> None: ...
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
    BUDGET_FIELD_NUMBER: _ClassVar[int]
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
    budget: float
    def __init__(self, env: _Optional[str] = ..., ego_goal: _Optional[str] = ..., partners: _Optional[_Iterable[_Union[PartnerSpec, _Mapping]]] = ..., method: _Optional[str] = ..., temperature: _Optional[float] = ..., seed: _Optional[int] = ..., alias: _Optional[str] = ..., versions: _Optional[_Mapping[str, int]] = ..., belief: _Optional[_Union[BeliefSettings, _Mapping]] = ..., regret_bound: _Optional[float] = ..., budget: _Optional[float] = ...) -> None: ...

class ObservedAction(_message.Message):
    __slots__ = ("index", "action")
    INDEX_FIELD_NUMBER: _ClassVar[int]
    ACTION_FIELD_NUMBER: _ClassVar[int]
    index: int
    action: int
    def __init__(self, index: _Optional[int] = ..., action: _Optional[int] = ...) -> None: ...

class EpisodeStep(_message.Message):
    __slots__ = ("settings", "observation", "state", "ego_index", "observed")
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
    def __init__(self, settings: _Optional[_Union[EpisodeSettings, _Mapping]] = ..., observation: _Optional[_Iterable[float]] = ..., state: _Optional[_Union[State, _Mapping]] = ..., ego_index: _Optional[int] = ..., observed: _Optional[_Iterable[_Union[ObservedAction, _Mapping]]] = ...) -> None: ...

class PartnerWeight(_message.Message):
    __slots__ = ("index", "weight")
    INDEX_FIELD_NUMBER: _ClassVar[int]
    WEIGHT_FIELD_NUMBER: _ClassVar[int]
    index: int
    weight: float
    def __init__(self, index: _Optional[int] = ..., weight: _Optional[float] = ...) -> None: ...

class Diagnostics(_message.Message):
    __slots__ = ("task_entropy", "task_weight", "partner_weights")
    TASK_ENTROPY_FIELD_NUMBER: _ClassVar[int]
    TASK_WEIGHT_FIELD_NUMBER: _ClassVar[int]
    PARTNER_WEIGHTS_FIELD_NUMBER: _ClassVar[int]
    task_entropy: float
    task_weight: float
    partner_weights: _containers.RepeatedCompositeFieldContainer[PartnerWeight]
    def __init__(self, task_entropy: _Optional[float] = ..., task_weight: _Optional[float] = ..., partner_weights: _Optional[_Iterable[_Union[PartnerWeight, _Mapping]]] = ...) -> None: ...

class ModelUsed(_message.Message):
    __slots__ = ("role", "name", "version", "sha256", "partner_index", "goal")
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
    def __init__(self, role: _Optional[str] = ..., name: _Optional[str] = ..., version: _Optional[int] = ..., sha256: _Optional[str] = ..., partner_index: _Optional[int] = ..., goal: _Optional[str] = ...) -> None: ...

class GoalProb(_message.Message):
    __slots__ = ("goal", "prob")
    GOAL_FIELD_NUMBER: _ClassVar[int]
    PROB_FIELD_NUMBER: _ClassVar[int]
    goal: str
    prob: float
    def __init__(self, goal: _Optional[str] = ..., prob: _Optional[float] = ...) -> None: ...

class PartnerBelief(_message.Message):
    __slots__ = ("index", "top", "entropy", "observed_action", "updates")
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
    def __init__(self, index: _Optional[int] = ..., top: _Optional[_Iterable[_Union[GoalProb, _Mapping]]] = ..., entropy: _Optional[float] = ..., observed_action: _Optional[int] = ..., updates: _Optional[int] = ...) -> None: ...

class ActResponse(_message.Message):
    __slots__ = ("probs", "action", "greedy_action", "action_meaning", "method", "diagnostics", "models", "beliefs", "budget")
    PROBS_FIELD_NUMBER: _ClassVar[int]
    ACTION_FIELD_NUMBER: _ClassVar[int]
    GREEDY_ACTION_FIELD_NUMBER: _ClassVar[int]
    ACTION_MEANING_FIELD_NUMBER: _ClassVar[int]
    METHOD_FIELD_NUMBER: _ClassVar[int]
    DIAGNOSTICS_FIELD_NUMBER: _ClassVar[int]
    MODELS_FIELD_NUMBER: _ClassVar[int]
    BELIEFS_FIELD_NUMBER: _ClassVar[int]
    BUDGET_FIELD_NUMBER: _ClassVar[int]
    probs: _containers.RepeatedScalarFieldContainer[float]
    action: int
    greedy_action: int
    action_meaning: str
    method: str
    diagnostics: Diagnostics
    models: _containers.RepeatedCompositeFieldContainer[ModelUsed]
    beliefs: _containers.RepeatedCompositeFieldContainer[PartnerBelief]
    budget: Budget
    def __init__(self, probs: _Optional[_Iterable[float]] = ..., action: _Optional[int] = ..., greedy_action: _Optional[int] = ..., action_meaning: _Optional[str] = ..., method: _Optional[str] = ..., diagnostics: _Optional[_Union[Diagnostics, _Mapping]] = ..., models: _Optional[_Iterable[_Union[ModelUsed, _Mapping]]] = ..., beliefs: _Optional[_Iterable[_Union[PartnerBelief, _Mapping]]] = ..., budget: _Optional[_Union[Budget, _Mapping]] = ...) -> None: ...

class Budget(_message.Message):
    __slots__ = ("spent", "total", "value")
    SPENT_FIELD_NUMBER: _ClassVar[int]
    TOTAL_FIELD_NUMBER: _ClassVar[int]
    VALUE_FIELD_NUMBER: _ClassVar[int]
    spent: float
    total: float
    value: float
    def __init__(self, spent: _Optional[float] = ..., total: _Optional[float] = ..., value: _Optional[float] = ...) -> None: ...

class ActColumns(_message.Message):
    __slots__ = ("method", "models", "rows", "n_actions", "probs", "actions", "greedy_actions", "action_meanings", "task_entropies", "task_weights", "partner_indices", "partner_weights", "budget_spent", "budget_total", "budget_value")
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
    BUDGET_SPENT_FIELD_NUMBER: _ClassVar[int]
    BUDGET_TOTAL_FIELD_NUMBER: _ClassVar[int]
    BUDGET_VALUE_FIELD_NUMBER: _ClassVar[int]
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
    budget_spent: _containers.RepeatedScalarFieldContainer[float]
    budget_total: _containers.RepeatedScalarFieldContainer[float]
    budget_value: _containers.RepeatedScalarFieldContainer[float]
    def __init__(self, method: _Optional[str] = ..., models: _Optional[_Iterable[_Union[ModelUsed, _Mapping]]] = ..., rows: _Optional[int] = ..., n_actions: _Optional[int] = ..., probs: _Optional[_Iterable[float]] = ..., actions: _Optional[_Iterable[int]] = ..., greedy_actions: _Optional[_Iterable[int]] = ..., action_meanings: _Optional[_Iterable[str]] = ..., task_entropies: _Optional[_Iterable[float]] = ..., task_weights: _Optional[_Iterable[float]] = ..., partner_indices: _Optional[_Iterable[int]] = ..., partner_weights: _Optional[_Iterable[float]] = ..., budget_spent: _Optional[_Iterable[float]] = ..., budget_total: _Optional[_Iterable[float]] = ..., budget_value: _Optional[_Iterable[float]] = ...) -> None: ...

class ActBatchResponse(_message.Message):
    __slots__ = ("results", "columns")
    RESULTS_FIELD_NUMBER: _ClassVar[int]
    COLUMNS_FIELD_NUMBER: _ClassVar[int]
    results: _containers.RepeatedCompositeFieldContainer[ActResponse]
    columns: ActColumns
    def __init__(self, results: _Optional[_Iterable[_Union[ActResponse, _Mapping]]] = ..., columns: _Optional[_Union[ActColumns, _Mapping]] = ...) -> None: ...

class ListEnvsRequest(_message.Message):
    __slots__ = ()
    def __init__(self) -> None: ...

class ObservationLayout(_message.Message):
    __slots__ = ("n_agents", "obs_dim", "features")
    N_AGENTS_FIELD_NUMBER: _ClassVar[int]
    OBS_DIM_FIELD_NUMBER: _ClassVar[int]
    FEATURES_FIELD_NUMBER: _ClassVar[int]
    n_agents: int
    obs_dim: int
    features: _containers.RepeatedScalarFieldContainer[str]
    def __init__(self, n_agents: _Optional[int] = ..., obs_dim: _Optional[int] = ..., features: _Optional[_Iterable[str]] = ...) -> None: ...

class EnvInfo(_message.Message):
    __slots__ = ("name", "goals", "action_meanings", "max_agents", "observation_layouts", "state_layout", "pair_obs_dim", "methods")
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
    def __init__(self, name: _Optional[str] = ..., goals: _Optional[_Iterable[str]] = ..., action_meanings: _Optional[_Iterable[str]] = ..., max_agents: _Optional[int] = ..., observation_layouts: _Optional[_Iterable[_Union[ObservationLayout, _Mapping]]] = ..., state_layout: _Optional[_Iterable[str]] = ..., pair_obs_dim: _Optional[int] = ..., methods: _Optional[_Iterable[str]] = ...) -> None: ...

class ListEnvsResponse(_message.Message):
    __slots__ = ("envs",)
    ENVS_FIELD_NUMBER: _ClassVar[int]
    envs: _containers.RepeatedCompositeFieldContainer[EnvInfo]
    def __init__(self, envs: _Optional[_Iterable[_Union[EnvInfo, _Mapping]]] = ...) -> None: ...
