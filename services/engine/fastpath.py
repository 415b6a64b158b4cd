"""The single-row path of `InferenceEngine.act`: one observation, method sl, nail or aail.

At batch 1 numpy's per-call overhead, not arithmetic, sets the latency, so this path makes as
few numpy calls as it can and does the rest on Python floats. Same inputs, semantics, errors,
models and sampled stream as the general path (`assembly` + `policy.blend.blend`); the numbers
agree up to float32 rounding (~1e-7 relative in Q): the forward runs R matrix-vector products
instead of padded matrix products, and the task Q is averaged over its views in float64 (the
general path averages in float32).

| step     | what                                                                       |
|----------|----------------------------------------------------------------------------|
| layout   | which input row feeds which member, where each partner's Q-values lie, the |
|          | models used, the input gather: built once per (env, agent count, members, |
|          | partners) and kept on the stacked group (`StackedGroup.memo`, immutable)   |
| inputs   | one `gathers.Gather` of the observation when the domain's views are        |
|          | selections (proved on probes), else the domain's view functions            |
| forward  | `networks.forward_rows` per partition: the task net on K one-row members,  |
|          | each impact net on one (weights sliced, not copied)                        |
| reduce   | task Q = mean of the K views; a goal distribution mixes its goals' Q-values |
|          | by probability (`mix_goal_beliefs`' expectation as a sequential sum, which |
|          | einsum's order matches to ~1e-16, not bit for bit; compiled, or numpy, from|
|          | `MIX_NUMPY_MIN` goals on: a whole belief has 35)                           |
| blend    | `policy.blend_fast.blend_row` (bit-identical to `policy.blend.blend`)      |
| sample   | `assembly.sample_actions`' inverse CDF on floats, same uniform stream      |

The path declines (returns None, the caller takes the general path) when a layout does not fit
`forward_rows`: an impact network that serves two partner slots, or more task views than the
group's `first_repeats`.
"""

from __future__ import annotations

from bisect import bisect_right
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import accumulate

import numpy as np

from envs.base import Domain
from policy.belief_compiled import compiled_mix
from policy.blend import BlendMethod
from policy.blend_fast import blend_row
from policy.regret_bound import keep_goal_row
from policy.row_forward import all_finite
from services.engine.assembly import finished_rows, goal_kept_of, models_used, regret_bound_of
from services.engine.errors import InvalidRequest
from services.engine.gathers import Builder, Gather, find_gather
from services.engine.messages import DEFAULT_TEMPERATURE, ActRequest, ActResult, Member, ModelUsed
from services.engine.networks import Partition, StackedGroup, forward_rows
from services.engine.validation import CheckedRequest

MEMO_MAX = 256  # layouts kept per stacked group (the memo is cleared when it grows past this)
TASK_VIEWS = -1  # an input source: the K task views (otherwise a partner's position)
# From this many goals on, a distribution's mix runs compiled (`policy.belief_compiled.compiled_mix`,
# ~1 µs for 35 goals) or in numpy (~4.5 µs) instead of Python (~14). `np.add.accumulate` adds the rows one after the other, as the Python loop does, so
# the bits are the same (a plain axis-0 `sum` would not be: with one action it sums pairwise).
MIX_NUMPY_MIN = 8


@dataclass(frozen=True, eq=False)
class PartInputs:
    """How one partition's input rows are built from an observation row."""

    part: Partition
    task_rows: int  # rows of the partition's first member (K for the task net, else 1)
    build: Builder  # obs (B, D) -> inputs (B, R, F) through the domain's view functions
    gather: Gather | None  # the same as one gather, when `gathers.find_gather` proved it


@dataclass(frozen=True, eq=False)
class RowLayout:
    parts: tuple[PartInputs, ...]
    n_views: int  # K: the task net's input rows, output rows 0..K-1
    partner_rows: tuple[tuple[int, ...], ...]  # per partner: the output row of each goal
    partner_rows_index: tuple[np.ndarray, ...]  # the same as index arrays (numpy mix)
    list_rows: bool  # whether a partner reads rows as Python lists (else only the task's)
    models: tuple[ModelUsed, ...]


def _builder(domain: Domain, n_agents: int, sources: list[int], indices: list[int]) -> Builder:
    """obs (B, D) -> (B, R, F): per source, the K task views or a partner's impact view."""

    def build(obs_BD: np.ndarray) -> np.ndarray:
        blocks = [
            domain.task_views(obs_BD, n_agents)
            if source == TASK_VIEWS
            else domain.impact_view(obs_BD, n_agents, indices[source])[:, None, :]
            for source in sources
        ]
        return blocks[0] if len(blocks) == 1 else np.concatenate(blocks, axis=1)

    return build


# gathers by (env, agents, sources, partner indices, obs_dim): what a builder computes depends on
# nothing else, so a new stacked group (a top-k blend's next goal set) reuses the probe's result
# instead of proving it again (~0.5 ms)
_GATHERS: dict[tuple[object, ...], Gather | None] = {}


def _gather(
    build: Builder,
    domain: Domain,
    n_agents: int,
    sources: list[int],
    indices: list[int],
    obs_dim: int,
) -> Gather | None:
    """`find_gather(build, obs_dim)`, remembered by what `build` depends on."""
    key = (domain.name, n_agents, tuple(sources), tuple(indices), obs_dim)
    if key not in _GATHERS:
        if len(_GATHERS) >= MEMO_MAX:
            _GATHERS.clear()
        _GATHERS[key] = find_gather(build, obs_dim)
    return _GATHERS[key]


def _layout(
    checked: CheckedRequest, members: Sequence[Member], group: StackedGroup
) -> RowLayout | None:
    """The row layout, or None when it does not fit `forward_rows` (module docstring)."""
    domain, n_agents = checked.runtime.domain, checked.n_agents
    obs_dim = checked.obs_BD.shape[1]
    n_views = domain.task_views(np.zeros((1, obs_dim), np.float32), n_agents).shape[1]
    member_of = {goal: j for j, (role, goal) in enumerate(members) if role == "impact"}
    source_of: dict[int, int] = {0: TASK_VIEWS}  # member -> the partner whose view it reads
    for position, partner in enumerate(checked.partners if len(members) > 1 else ()):
        for goal in partner.goals:
            if member_of[goal] in source_of:
                return None  # one impact net for two slots: the general path stacks it
            source_of[member_of[goal]] = position
    indices = [partner.index for partner in checked.partners]
    parts, first_row, row = [], {}, 0  # output rows: the partitions' rows one after the other
    for part in group.partitions:
        task_rows = n_views if part.members[0] == 0 else 1
        if task_rows > part.first_repeats:
            return None
        for j in part.members:
            first_row[j] = row
            row += task_rows if j == 0 else 1
        sources = [source_of[j] for j in part.members]
        build = _builder(domain, n_agents, sources, indices)
        parts.append(
            PartInputs(
                part, task_rows, build, _gather(build, domain, n_agents, sources, indices, obs_dim)
            )
        )
    partner_rows = tuple(
        tuple(first_row[member_of[goal]] for goal in partner.goals) if len(members) > 1 else ()
        for partner in checked.partners
    )
    models = tuple(models_used(checked, members, group))
    rows_index = tuple(np.array(rows, dtype=np.intp) for rows in partner_rows)
    list_rows = any(
        p.probs is None or len(rows) < MIX_NUMPY_MIN
        for p, rows in zip(checked.partners, partner_rows, strict=True)
    )
    return RowLayout(tuple(parts), n_views, partner_rows, rows_index, list_rows, models)


def act_row(
    checked: CheckedRequest,
    request: ActRequest,
    members: Sequence[Member],
    group: StackedGroup,
    default_rng: np.random.Generator,
) -> list[ActResult] | None:
    """The one result of a single-row sl/nail/aail request, or None (module docstring)."""
    partners = checked.partners
    key = (
        checked.runtime.domain.name,
        checked.n_agents,
        tuple(members),
        tuple((p.index, p.goals) for p in partners),
    )
    layout = group.memo.get(key, False)
    if layout is False:
        layout = _layout(checked, members, group)
        if len(group.memo) >= MEMO_MAX:
            group.memo.clear()
        group.memo[key] = layout
    if layout is None:
        return None
    assert isinstance(layout, RowLayout)

    q_blocks: list[np.ndarray] = []  # (rows, A) float32 per partition
    for inputs in layout.parts:
        if inputs.gather is not None:
            x_R1F = inputs.gather(checked.obs_BD[0])
        else:
            x_R1F = inputs.build(checked.obs_BD)[0][:, None, :]
        q_R1A = forward_rows(inputs.part, x_R1F, inputs.task_rows)
        if not all_finite(q_R1A):
            raise InvalidRequest("observations", "values so large that the Q-values overflow")
        q_blocks.append(q_R1A[:, 0, :])
    q_RA = q_blocks[0] if len(q_blocks) == 1 else np.concatenate(q_blocks)
    n_views = layout.n_views
    # as Python floats: every row, or only the task's when the partners' mixes run in numpy
    q_rows: list[list[float]] = (q_RA if layout.list_rows else q_RA[:n_views]).tolist()
    # the task Q averaged over the K views (one per other agent), in float64
    q_task = [sum(column) / n_views for column in zip(*q_rows[:n_views], strict=True)]
    if finished_rows(request, checked) is not None:  # R3: the exact task Q is flat
        q_task = [sum(q_task) / len(q_task)] * len(q_task)
    q_impact = []
    for partner, rows, index in zip(
        partners, layout.partner_rows, layout.partner_rows_index, strict=True
    ):
        if partner.probs is None:
            q_impact += [q_rows[row] for row in rows]
        elif len(rows) >= MIX_NUMPY_MIN:  # the same sum as below, compiled or in numpy
            mixed_A = compiled_mix(partner.probs, q_RA, rows)
            if mixed_A is None:
                terms_GA = np.multiply(np.asarray(partner.probs)[:, None], q_RA[index], dtype=float)
                mixed_A = np.add.accumulate(terms_GA, axis=0)[-1].tolist()
            q_impact.append(mixed_A)
        elif rows:  # the expected impact Q under the goal distribution (§3.2)
            mixed = [0.0] * len(q_task)
            for p, row in zip(partner.probs, rows, strict=True):
                mixed = [acc + p * q for acc, q in zip(mixed, q_rows[row], strict=True)]
            q_impact.append(mixed)

    method: BlendMethod = request.method  # type: ignore[assignment]  # not jl here
    temperature = request.temperature or group.nets[0].alpha or DEFAULT_TEMPERATURE
    normalise = checked.runtime.domain.blend_normalisation == "standardise"
    epsilon = regret_bound_of(request, group, checked)
    blended = blend_row(
        method,
        q_task,
        q_impact,
        temperature,
        normalise=normalise,
        regret_bound=None if epsilon is None else float(epsilon[0]),
    )
    weights = blended.partner_weights_P if method != "sl" else [0.0] * len(checked.partners)
    rng = default_rng if request.seed is None else np.random.default_rng(request.seed)
    probs = blended.probs_A
    kept = goal_kept_of(request, checked, epsilon)
    if kept is not None:  # R4 of `policy.regret_bound`
        probs = keep_goal_row(probs, kept[0].tolist())
    # `assembly.sample_actions` on one row: the first action whose cumulative probability
    # exceeds u (the cdf never decreases, so that is the count of entries <= u)
    cdf = list(accumulate(probs))
    action = min(bisect_right(cdf, rng.random() * cdf[-1]), len(probs) - 1)
    greedy = probs.index(max(probs))
    return [
        ActResult(probs, action, greedy, method, blended.task_entropy, blended.task_weight, weights,
                  list(layout.models))
    ]  # fmt: skip
