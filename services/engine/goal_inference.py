"""The engine's side of online goal inference: how likely each goal makes a partner's
observed action, for every goal at once, and the partners' actions recovered from observations.
The belief itself (prior, forgetting, floor) is pure maths in `policy.belief`.

| step     | what                                                                       |
|----------|----------------------------------------------------------------------------|
| check    | env, observation (D,), partner indices, actions, temperature, alias, pins  |
| resolve  | `{env}/task/{g}` for EVERY goal g of the catalogue, in catalogue order, by |
|          | alias or pinned version (`model_cache`, as `act` does; one fixed set)      |
| stack    | one `StackedGroup` of the G task networks (cached by their versions)       |
| views    | per partner p its view of the pair, `domain.partner_view(obs, N, p)`       |
| forward  | one stacked pass per spec partition: the same (P, pair_obs_dim) rows go    |
|          | through all G networks, (1, P, F) @ (G, F, H) ... -> (G, P, A)             |
|          | (`policy.row_forward`)                                                     |
| softmax  | log softmax(Q_g / α_g)[a_p] (`policy.belief.boltzmann_log_likelihoods`'s  |
|          | arithmetic on the forward's layout: `_log_likelihoods`)                    |
| noise    | with `noise` η > 0: log((1 - η) π_g(a_p) + η / A)                          |
|          | (`policy.belief.mix_uniform_noise`)                                        |
| ahead    | `likelihood_table`: the same pass for every action a, before the actions   |
|          | are known; `LikelihoodTable.pick` then gives the same numbers (a session   |
|          | computes step t + 1's table right after answering step t)                  |
| pruned   | `goals`: the pass on those goals' networks only (a pruning session's       |
|          | active goals, `policy.belief_prune`): the same numbers as their columns of |
|          | the whole pass with the compiled forward (rows and members independent)    |

α per goal: the request's `temperature`, else `LIKELIHOOD_TEMPERING` × each task network's
training α (lineage; else `DEFAULT_TEMPERATURE`): a partner is modelled as acting by its own
task policy (eq. 2), tempered. Why tempered: a person or another robot does not act as the
ego's copy of its networks would (another training seed, noise, a hotter policy); at the
networks' own α one unexpected action all but rules its true goal out. The factor was
calibrated on partner types the report does not score (`reports/inference`, its discussion).
`noise` η (a session's `belief.noise`) mixes the tempered policy with uniform action noise, which
caps what one unexpected action can cost a goal; the engine's own default is 0 (the plain
tempered policy), a session's is `policy.belief.DEFAULT_NOISE`.

Approximation for N > 2 agents: the partner's task network sees only its pair with the ego (the
ego's observation does not hold the partner's views of the other agents in general), as the
impact networks do. With N = 2 the pair is the whole scene and there is nothing to approximate.

Errors: `InvalidRequest` naming `env`, `observation`, `partners[i].index`, `observed` (not one
action per partner), `observed[i].action`, `temperature`, `noise`, `alias`, `versions[name]`;
`ModelNotFound` (field `partners`) when a goal has no task network under the alias / version.

A session, which checked its inputs already, calls `checked_log_likelihoods` (the same pass
without the argument checks).

Recovering actions: an env may give its `Domain` an optional method
`recover_action(prev_obs_D, obs_D, n_agents, partner) -> int`, the most likely action of the
partner between two consecutive ego observations (the particle world's is exact: its dynamics are
deterministic). An env without it answers `InvalidRequest("observed")`: the client must send
each partner's action.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cache
from typing import Protocol, runtime_checkable

import numpy as np

from envs.base import Domain
from model_store.errors import brief
from policy.belief import check_noise, mix_uniform_noise
from policy.belief_compiled import compiled_log_softmax
from policy.row_forward import COMPILED as ROW_FORWARD
from policy.row_forward import row_forward
from services.engine.environments import EnvRuntime, env_runtime
from services.engine.errors import EngineError, InvalidRequest
from services.engine.messages import Member
from services.engine.model_cache import ModelCache
from services.engine.networks import StackedGroup, overflow_error
from services.engine.validation import check_alias, check_observations, check_versions

LIKELIHOOD_TEMPERING = 4.0  # the default likelihood's α over each network's training α
# whether a pass's rows are each what a pass of that row alone gives, bit for bit (then any
# subset of a table's partners can be served): the compiled forward computes each row alone;
# numpy's batched matmul may round a row differently with other rows
ROWS_INDEPENDENT = ROW_FORWARD
# z = Q - max Q with Q finite in float32, so |z| < 2^129: z / α overflows float64 (max ~2^1024)
# only for α below ~2^-895 ~ 1e-269
TINY_ALPHA = 1e-250


def _is_int(value: object) -> bool:
    return isinstance(value, int | np.integer) and not isinstance(value, bool)


def _is_real(value: object) -> bool:
    return isinstance(value, int | float | np.integer | np.floating) and not isinstance(value, bool)


@runtime_checkable
class RecoversActions(Protocol):
    """The optional `Domain` method used by `recover_partner_actions`."""

    def recover_action(
        self, prev_obs_D: np.ndarray, obs_D: np.ndarray, n_agents: int, partner: int
    ) -> int: ...


@dataclass(frozen=True)
class GoalNetworks:
    """Every task network of one env's goal catalogue, in catalogue order."""

    goals: tuple[str, ...]
    members: tuple[Member, ...]
    needs: tuple[tuple[str, str, str], ...]  # (model name, field to blame, why it is needed)


@cache
def _goal_networks(env: str) -> GoalNetworks:
    runtime = env_runtime(env)
    goals = runtime.domain.goals
    why = f"goal inference needs the task network of every goal of env {env!r}"
    return GoalNetworks(
        goals=tuple(goals),
        members=tuple(("task", g) for g in goals),
        needs=tuple((runtime.task_names[g], "partners", why) for g in goals),
    )


def _partner_views(
    runtime: EnvRuntime, obs_D: np.ndarray, n_agents: int, partners: tuple[int, ...]
) -> np.ndarray:
    """The partners' views of the pair (partner, ego) as one (1, P, F) float32 block."""
    domain: Domain = runtime.domain
    obs_1D = obs_D[None]
    views = [domain.partner_view(obs_1D, n_agents, p) for p in partners]
    return np.concatenate(views).astype(np.float32, copy=False)[None]


def _forward_all(
    group: StackedGroup, x_1PF: np.ndarray, goals: np.ndarray | None = None
) -> np.ndarray:
    """Q-values (G, P, A) of every member of the group on the same rows: one stacked pass per
    spec partition (one in total when every task network has the same architecture). `goals`
    (ascending member indices): only those members, (len(goals), P, A), one pass per run of
    consecutive members."""
    if goals is not None:
        return _forward_some(group, x_1PF, goals)
    if len(group.partitions) == 1:
        part = group.partitions[0]
        return row_forward(x_1PF, part.row_weights, 0, len(part.members), part.spec.activation)
    n_actions = group.nets[0].spec.n_actions
    q_GPA = np.empty((len(group.nets), x_1PF.shape[1], n_actions), dtype=np.float32)
    for part in group.partitions:
        members = len(part.members)
        q_GPA[list(part.members)] = row_forward(
            x_1PF, part.row_weights, 0, members, part.spec.activation
        )
    return q_GPA


def _forward_some(group: StackedGroup, x_1PF: np.ndarray, goals: np.ndarray) -> np.ndarray:
    """`_forward_all(group, x_1PF)[goals]` without the other members' passes."""
    n_actions = group.nets[0].spec.n_actions
    q_KPA = np.empty((len(goals), x_1PF.shape[1], n_actions), dtype=np.float32)
    wanted = goals.tolist()
    for part in group.partitions:
        if len(group.partitions) == 1:  # every member, in order: positions are the indices
            mine = list(enumerate(wanted))
        else:
            position = {member: i for i, member in enumerate(part.members)}
            mine = [(k, position[g]) for k, g in enumerate(wanted) if g in position]
        k = 0
        while k < len(mine):  # runs of consecutive members: one call each
            end = k + 1
            while end < len(mine) and mine[end][1] == mine[end - 1][1] + 1:
                end += 1
            start = mine[k][1]
            q_KPA[mine[k][0] : mine[k][0] + end - k] = row_forward(
                x_1PF, part.row_weights, start, end - k, part.spec.activation
            )
            k = end
    return q_KPA


def _training_alphas(group: StackedGroup) -> tuple[np.ndarray, bool]:
    """Each member's likelihood temperature (`LIKELIHOOD_TEMPERING` × its training α), (G, 1, 1)
    to divide (G, P, A) Q-values by goal, and whether one is below `TINY_ALPHA`."""
    alpha_G = LIKELIHOOD_TEMPERING * group.alpha_G
    return alpha_G[:, None, None], bool(alpha_G.min() < TINY_ALPHA)


def _scaled(
    q_GPA: np.ndarray, alpha: np.ndarray | float, tiny: bool
) -> tuple[np.ndarray, np.ndarray]:
    """z = (Q - max Q) / α as float64 (G, P, A) and log Σ_a exp z (G, P): the two parts of
    log softmax(Q / α). The Q-values are finite (checked by the caller), so the division by α
    is the only step that can overflow (to -inf, meant), and only when an α is `tiny` (<
    `TINY_ALPHA`): errstate (a cost on every call) only then."""
    z = q_GPA.astype(np.float64)
    z -= z.max(axis=2, keepdims=True)  # <= 0, the arg-max exactly 0
    if tiny:
        with np.errstate(over="ignore"):
            z /= alpha
    else:
        z /= alpha
    return z, np.log(np.exp(z).sum(axis=2))  # >= log 1 = 0: the arg-max term is exp(0)


def _log_likelihoods(
    q_GPA: np.ndarray, actions_P: np.ndarray, alpha: np.ndarray | float, tiny: bool
) -> np.ndarray:
    """`boltzmann_log_likelihoods(q_GPA.transpose(1, 0, 2), actions_P, α, validate=False)` in
    the forward's (G, P, A) layout: compiled (`policy.belief_compiled.compiled_log_softmax`),
    else the same arithmetic in numpy with fewer calls (`_scaled`); equal within the tolerance
    of tests/services/engine/test_goal_likelihoods.py."""
    table = compiled_log_softmax(q_GPA, alpha)  # z - log_norm, compiled
    if table is not None:
        if len(actions_P) == 1:
            return table[:, 0, int(actions_P[0])][None]
        return table[:, np.arange(len(actions_P)), actions_P].T
    z, log_norm_GP = _scaled(q_GPA, alpha, tiny)
    if len(actions_P) == 1:  # one partner (the usual case): plain indexing, the same numbers
        return (z[:, 0, int(actions_P[0])] - log_norm_GP[:, 0])[None]
    return (z[:, np.arange(len(actions_P)), actions_P] - log_norm_GP).T


def _check_observation(
    observation: object, runtime: EnvRuntime, field: str
) -> tuple[np.ndarray, int]:
    """One observation (D,) as float32 and its agent count; errors name `field`."""
    obs = observation if isinstance(observation, np.ndarray) else None
    if obs is None:
        try:
            obs = np.asarray(observation, dtype=np.float64)
        except (TypeError, ValueError):
            raise InvalidRequest(field, "expected a vector of numbers") from None
    if obs.ndim != 1:
        raise InvalidRequest(
            field, f"expected one observation of shape (obs_dim,), got {obs.shape}"
        )
    try:
        obs_1D, n_agents = check_observations(obs[None], runtime, 1)
    except EngineError as exc:
        raise exc.renamed(field) from None
    return obs_1D[0], n_agents


def _check_partners(partners: object, n_agents: int) -> tuple[int, ...]:
    if not isinstance(partners, Sequence) or isinstance(partners, str):
        raise InvalidRequest("partners", "expected a list of partner indices")
    seen: list[int] = []
    for i, index in enumerate(partners):
        field = f"partners[{i}].index"
        if not _is_int(index):
            raise InvalidRequest(field, f"expected an integer, got {brief(index)}")
        if not 1 <= index <= n_agents - 1:
            expected = f"1..{n_agents - 1}" if n_agents > 1 else "no partner index (only the ego)"
            raise InvalidRequest(
                field,
                f"{brief(index)} out of range: the observation holds {n_agents} agent(s), "
                f"expected {expected}",
            )
        if index in seen:
            raise InvalidRequest(field, f"partner index {index} given twice")
        seen.append(int(index))
    return tuple(seen)


def _check_actions(actions: object, n_partners: int, n_actions: int) -> np.ndarray:
    if not isinstance(actions, Sequence | np.ndarray) or isinstance(actions, str):
        raise InvalidRequest("observed", "expected one action per partner")
    if len(actions) != n_partners:
        raise InvalidRequest(
            "observed", f"expected one action per partner ({n_partners}), got {len(actions)}"
        )
    for i, action in enumerate(actions):
        if not _is_int(action) or not 0 <= action < n_actions:
            raise InvalidRequest(
                f"observed[{i}].action",
                f"expected an action in 0..{n_actions - 1}, got {brief(action)}",
            )
    return np.asarray(actions, dtype=np.int64)


def goal_log_likelihoods(
    cache_: ModelCache,
    env: str,
    observation: np.ndarray,
    partners: Sequence[int],
    actions: Sequence[int],
    *,
    alias: str,
    versions: Mapping[str, int] | None,
    temperature: float | None,
    noise: float = 0.0,
) -> np.ndarray:
    """log π_g(actions[p] | partner p's view of `observation`) for every goal g, (P, G) in the
    env's goal order (mixed with uniform action noise η = `noise`). `observation` is the ego's
    observation when the partners acted."""
    runtime = env_runtime(env)
    obs_D, n_agents = _check_observation(observation, runtime, "observation")
    indices = _check_partners(partners, n_agents)
    actions_P = _check_actions(actions, len(indices), runtime.domain.n_actions)
    if temperature is not None and (
        not _is_real(temperature) or not 0 < temperature < float("inf")
    ):
        raise InvalidRequest(
            "temperature", f"expected a finite number > 0, got {brief(temperature)}"
        )
    try:
        noise = check_noise(noise)
    except ValueError:
        raise InvalidRequest("noise", f"expected a number in [0, 1), got {brief(noise)}") from None
    check_alias(alias)
    pinned = {} if versions is None else versions
    check_versions(pinned)
    return checked_log_likelihoods(
        cache_,
        runtime,
        obs_D,
        n_agents,
        indices,
        actions_P,
        alias=alias,
        versions=pinned,
        temperature=temperature,
        noise=noise,
    )


def checked_log_likelihoods(
    cache_: ModelCache,
    runtime: EnvRuntime,
    obs_D: np.ndarray,
    n_agents: int,
    partners: Sequence[int],
    actions_P: np.ndarray,
    *,
    alias: str,
    versions: Mapping[str, int],
    temperature: float | None,
    goals: np.ndarray | None = None,
    noise: float = 0.0,
) -> np.ndarray:
    """`goal_log_likelihoods` on arguments its checks passed: `obs_D` a finite float32 (D,)
    observation of `n_agents` agents, partner indices in 1..n_agents-1 (none twice), int64
    actions in range, a valid alias and pins, a temperature None or finite > 0, a noise in
    [0, 1). Internal, for a caller that checked them already (a session: its settings once,
    each step's observation and `observed` entries; it checks the indices against the stored
    observation's agents). `goals` (ascending catalogue indices): only those goals' columns,
    (P, len(goals))."""
    group = task_group(cache_, runtime, alias, versions)
    if not len(partners):
        return np.zeros((0, len(group.nets) if goals is None else len(goals)))
    q_GPA = _q_values(group, runtime, obs_D, n_agents, tuple(partners), goals)
    cache_.stats.likelihood_passes += 1
    lik = _log_likelihoods(q_GPA, actions_P, *_alphas(group, temperature, goals))
    return mix_uniform_noise(lik, noise, q_GPA.shape[2])


def task_group(
    cache_: ModelCache, runtime: EnvRuntime, alias: str, versions: Mapping[str, int]
) -> StackedGroup:
    """The stacked group of every goal's task network, by alias or pinned versions (the same
    object while no alias moves: a `LikelihoodTable` checks it with `is`)."""
    nets = _goal_networks(runtime.domain.name)
    return cache_.resolve_group(nets.needs, alias, versions, nets.members, runtime.domain)[1]


def _q_values(
    group: StackedGroup,
    runtime: EnvRuntime,
    obs_D: np.ndarray,
    n_agents: int,
    partners: tuple[int, ...],
    goals: np.ndarray | None = None,
) -> np.ndarray:
    """Every task network (or those of `goals`) on each partner's view: finite (G, P, A)
    float32 Q-values."""
    x_1PF = _partner_views(runtime, obs_D, n_agents, partners)
    if ROW_FORWARD:  # compiled: no floating-point warnings to silence
        q_GPA = _forward_all(group, x_1PF, goals)
    else:
        with np.errstate(over="ignore", invalid="ignore"):  # huge inputs: refused just below
            q_GPA = _forward_all(group, x_1PF, goals)
    if not np.isfinite(q_GPA).all():  # a huge observation's fault, or a network's
        raise overflow_error(group, obs_D, "observation")
    return q_GPA


def _alphas(
    group: StackedGroup, temperature: float | None, goals: np.ndarray | None = None
) -> tuple[np.ndarray | float, bool]:
    """The Boltzmann temperature per goal (the request's, else each network's tempered α; of
    `goals` only when given) and whether one is below `TINY_ALPHA`."""
    if temperature is None:
        alpha, tiny = _training_alphas(group)
        return (alpha if goals is None else alpha[goals]), tiny
    return float(temperature), temperature < TINY_ALPHA


@dataclass(frozen=True, eq=False)
class LikelihoodTable:
    """log π_g(a | partner p's view of one observation) for EVERY action a, computed before
    the actions are known: a session scores step t + 1's evidence (the partners' actions at
    o_t) with the table it computed right after answering step t (`likelihood_table`).

    `pick` returns exactly what `checked_log_likelihoods` would on the same observation,
    networks and noise, bit for bit: z - log_norm subtracted, and the noise mixed in, per
    element either way. Rows are independent with the compiled forward, so any subset of a
    table's partners is served; with numpy a table serves its own partner tuple only
    (`ROWS_INDEPENDENT`).
    """

    group: StackedGroup  # the task networks it was computed with
    partners: tuple[int, ...]
    logp_GPA: np.ndarray  # (G, P, A) float64; (len(goals), P, A) with `goals`
    goals: tuple[int, ...] | None = None  # the goals scored (a pruning session's); None: all

    def pick(
        self, group: StackedGroup, partners: Sequence[int], actions_P: np.ndarray
    ) -> np.ndarray | None:
        """(E, G) log-likelihoods of `actions_P` taken by `partners`, or None when the table
        cannot serve them: other networks (an alias moved) or other partner rows."""
        if group is not self.group:
            return None
        wanted = tuple(partners)
        if wanted == self.partners:
            rows: Sequence[int] = range(len(wanted))
        elif ROWS_INDEPENDENT and set(wanted) <= set(self.partners):
            rows = [self.partners.index(p) for p in wanted]
        else:
            return None
        if len(wanted) == 1:
            return self.logp_GPA[:, rows[0], int(actions_P[0])][None]
        return self.logp_GPA[:, list(rows), actions_P].T


def likelihood_table(
    cache_: ModelCache,
    runtime: EnvRuntime,
    obs_D: np.ndarray,
    n_agents: int,
    partners: tuple[int, ...],
    *,
    alias: str,
    versions: Mapping[str, int],
    temperature: float | None,
    goals: np.ndarray | None = None,
    noise: float = 0.0,
) -> LikelihoodTable:
    """The `LikelihoodTable` of `partners` on `obs_D`, arguments as `checked_log_likelihoods`
    takes them (errors too: `ModelNotFound`, an observation whose Q-values overflow)."""
    group = task_group(cache_, runtime, alias, versions)
    q_GPA = _q_values(group, runtime, obs_D, n_agents, partners, goals)
    alpha, tiny = _alphas(group, temperature, goals)
    z_GPA = compiled_log_softmax(q_GPA, alpha)  # the numpy lines' bits, compiled
    if z_GPA is None:
        z_GPA, log_norm_GP = _scaled(q_GPA, alpha, tiny)
        z_GPA -= log_norm_GP[:, :, None]  # in place: the same subtraction as `_log_likelihoods`'
    cache_.stats.likelihood_tables += 1
    return LikelihoodTable(
        group,
        partners,
        mix_uniform_noise(z_GPA, noise, q_GPA.shape[2]),
        None if goals is None else tuple(goals.tolist()),
    )


def recover_partner_actions(
    env: str, previous: np.ndarray, current: np.ndarray, partners: Sequence[int]
) -> list[int]:
    """The most likely action of each partner between two consecutive ego observations, by the
    env's `recover_action`; `InvalidRequest("observed")` for an env without one."""
    runtime = env_runtime(env)
    domain = runtime.domain
    if not isinstance(domain, RecoversActions):
        raise InvalidRequest(
            "observed",
            f"env {domain.name!r} cannot recover actions from consecutive observations; "
            "send each partner's action",
        )
    prev_D, n_prev = _check_observation(previous, runtime, "previous")
    obs_D, n_agents = _check_observation(current, runtime, "observation")
    if n_prev != n_agents:
        raise InvalidRequest(
            "observation",
            f"holds {n_agents} agent(s) but the previous observation held {n_prev}: "
            "actions can only be recovered between observations of the same agents",
        )
    indices = _check_partners(partners, n_agents)
    return [int(domain.recover_action(prev_D, obs_D, n_agents, p)) for p in indices]
