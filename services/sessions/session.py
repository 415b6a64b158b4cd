"""`Session`: one session's state and its step, shared by the REST store and the gRPC `Episode`.

    session = Session(engine, SessionSettings("particle", "a2", (SessionPartner(1, infer=True),)))
    first = session.step(obs_0)                                   # no evidence yet: the prior
    later = session.step(obs_1, observed=[Observed(1, action=3)])  # a_0 of partner 1, then act

Step semantics. Step t carries the ego's observation o_t and, optionally, the actions a_{t-1}
the inferred partners took between o_{t-1} and o_t (or `action=None`: recover it from o_{t-1} and
o_t with the env's `recover_action`). The session first updates each observed partner's belief
with the Boltzmann likelihood π_g(a_{t-1} | the partner's view of o_{t-1}) of every goal g
(eq. 2 of the paper, all task networks in one pass: `engine.goal_log_likelihoods` on the STORED
previous observation; tempered and mixed with uniform action noise by `belief.temperature` and
`belief.noise`), by `policy.belief.update_log_belief` (forgetting toward the prior, floor).
It then acts on o_t with each inferred partner's goal distribution =
`policy.belief.blend_goal_probs` of its new belief (default: every goal, in catalogue order, so
the act's networks are the same at every step; `blend_mass` < 1 or `blend_max_goals` keep only
the top goals, served from every goal's stacked group while the set keeps changing: the
engine's "Goal distributions"); announced
partners as given. A partner not in `observed` keeps its belief. With a seed, step t samples
with seed + t (the `Episode` rule).

A step is all or nothing: it computes the new belief and the action on copies and commits them
(belief, previous observation, counters) only when everything succeeded, so a bad step changes
nothing. Steps are serialised by a per-session lock; `expected_step` turns a stale or repeated
step into `StepConflict` instead of a second update.

Goal pruning (`belief.prune_below` τ > 0; `policy.belief_prune`, docs/method.md). The update
scores only the active goals (each partner's goals at or above τ, and its most probable), in
the table scored ahead or on demand, and a partner whose step's error bound exceeds
`belief.prune_error` δ gets the other goals scored too (the exact update). The act blends each
partner's goals at or above τ of its new belief (and its most probable) where the goals left
out hold at most δ of it, else the whole belief: a set that changes only when a goal crosses
τ, so the engine stacks it once it comes twice (its "Goal distributions").

State held: the settings (checked once), one log-belief row (G,) per inferred partner, the
previous observation, the next step's index and per-partner counters, and what the last belief
says (`policy.belief.belief_views`: the blend's distribution and the summary, one exp for all
partners), which a step without evidence reuses; and the next step's likelihood table
(below: G x P x A float64 per inferred partner).

Scoring ahead (`prepare_next`, on by default; `prefetch=False` turns it off). Step t + 1's
evidence is scored on o_t, which step t already holds: right after step t's answer is sent, the
transport calls `prepare_next`, which runs the likelihood pass on o_t for every action
(`goal_inference.likelihood_table`, G x P x A numbers), so that step t + 1 only picks its
actions' entries instead of running the pass while the client waits (docs/performance.md has
its share of a step). The numbers are those of the pass run at step t + 1, bit for bit; a step
uses the table only if it was made for that step, for those partners (`LikelihoodTable.pick`)
and with the task networks the aliases resolve to at that step (a hot reload in between: the
pass runs again). New settings drop it. The CPU work is the same, moved off the step's
latency; a session whose last step brought no evidence (after its first) prepares nothing.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from model_store.errors import brief
from policy.belief import BeliefView, belief_views
from policy.belief_prune import active_goals
from services.engine import (
    ActRequest,
    ActResult,
    EngineError,
    InferenceEngine,
    InvalidRequest,
)
from services.engine.goal_inference import (
    LikelihoodTable,
    checked_log_likelihoods,
    likelihood_table,
    task_group,
)
from services.engine.validation import (
    CheckedPartner,
    CheckedRequest,
    check_observations,
    check_partner_index,
)
from services.sessions.checks import CheckedSettings, check_observed, check_settings
from services.sessions.errors import StepConflict
from services.sessions.messages import (
    TOP_GOALS,
    Observed,
    PartnerBelief,
    SessionSettings,
    SessionState,
    SessionStepResult,
)

FLOAT32_MAX = float(np.finfo(np.float32).max)


class Session:
    """One session: settings, beliefs, previous observation, counters (module docstring)."""

    def __init__(
        self,
        engine: InferenceEngine,
        settings: SessionSettings,
        session_id: str = "",
        *,
        first_step: int = 0,
        previous_observation: ArrayLike | None = None,
        prefetch: bool = True,
        budget_state: tuple[float, float, float] | None = None,
        checked: CheckedSettings | None = None,
    ) -> None:
        self.engine = engine
        self.session_id = session_id
        self.prefetch = prefetch
        self._lock = threading.Lock()
        # `checked`: `check_settings(settings)` made before (the shared store's per-process cache)
        self._checked = checked if checked is not None else check_settings(settings)
        self._log_belief_PG = self._checked.initial_PG.copy()
        self._updates = [0] * len(self._checked.inferred)
        self._last_actions: list[int | None] = [None] * len(self._checked.inferred)
        self._previous: np.ndarray | None = None  # (1, D) float32
        self._previous_agents = 0  # the agents `_previous` holds
        # the views of the last committed belief: a step without evidence reuses them
        self._last_views: tuple[np.ndarray, list[BeliefView]] | None = None
        if previous_observation is not None:
            self._previous, self._previous_agents = self._observation(previous_observation)
        self._next_step = self._first_step = first_step
        # aail_budget's episode state (S spent, B budget, V the ego's task value) after the last
        # step; None before it (`budget_state`: where an episode begun without the session stood)
        self._budget: tuple[float, float, float] | None = budget_state
        # scoring ahead: the partners whose actions the next step is expected to bring, and
        # the table made for them (the step it serves, the table)
        self._table_partners: tuple[int, ...] = ()
        self._table: tuple[int, LikelihoodTable] | None = None

    # --- state kept elsewhere (services.sessions.shared) ------------------------------------
    def export_state(self) -> SessionState:
        """What the next step needs, as plain values and arrays (copies): with the settings,
        `restore` makes a session that answers every later step as this one would. Derived
        caches (the belief's views, the table scored ahead) are left out: a restored session
        recomputes them, with the same numbers."""
        with self._lock:
            previous = None if self._previous is None else self._previous.copy()
            return SessionState(
                first_step=self._first_step,
                next_step=self._next_step,
                log_belief_PG=self._log_belief_PG.copy(),
                updates=tuple(self._updates),
                last_actions=tuple(self._last_actions),
                previous=previous,
                previous_agents=self._previous_agents,
                budget=self._budget,
                table_partners=self._table_partners,
            )

    @classmethod
    def restore(
        cls,
        engine: InferenceEngine,
        checked: CheckedSettings,
        state: SessionState,
        session_id: str = "",
        *,
        prefetch: bool = True,
    ) -> Session:
        """The session `export_state` described, over `checked` = `check_settings` of its
        settings (checked once per process and shared: it is read only). `ValueError` when the
        state does not fit the settings (rows, goals, counters)."""
        rows, goals = len(checked.inferred), len(checked.goals)
        if state.log_belief_PG.shape != (rows, goals) or state.log_belief_PG.dtype != np.float64:
            raise ValueError(
                f"log_belief_PG: expected float64 {(rows, goals)}, got "
                f"{state.log_belief_PG.dtype} {state.log_belief_PG.shape}"
            )
        if len(state.updates) != rows or len(state.last_actions) != rows:
            raise ValueError(f"updates, last_actions: expected {rows} entries each")
        if state.previous is not None and (
            state.previous.dtype != np.float32
            or state.previous.ndim != 2
            or state.previous.shape[0] != 1
            or checked.runtime.agents_by_obs_dim.get(state.previous.shape[1])
            != state.previous_agents
        ):
            raise ValueError("previous: expected a float32 (1, D) observation of its agents")
        if not 0 <= state.first_step <= state.next_step:
            raise ValueError("next_step: expected >= first_step >= 0")
        session = cls.__new__(cls)
        session.engine = engine
        session.session_id = session_id
        session.prefetch = prefetch
        session._lock = threading.Lock()
        session._checked = checked
        session._log_belief_PG = state.log_belief_PG
        session._updates = list(state.updates)
        session._last_actions = list(state.last_actions)
        session._previous = state.previous
        session._previous_agents = state.previous_agents if state.previous is not None else 0
        session._last_views = None
        session._next_step, session._first_step = state.next_step, state.first_step
        session._budget = state.budget
        session._table_partners = state.table_partners
        session._table = None
        return session

    # --- read ------------------------------------------------------------------------------
    @property
    def settings(self) -> SessionSettings:
        return self._checked.settings

    @property
    def checked(self) -> CheckedSettings:
        """`check_settings` of the settings (read only; sessions of equal settings may share it)."""
        return self._checked

    @property
    def next_step(self) -> int:
        """The index the next step gets (= the steps taken so far, plus `first_step`)."""
        return self._next_step

    def snapshot(self) -> tuple[int, tuple[PartnerBelief, ...]]:
        """The next step's index and each inferred partner's belief, read together."""
        with self._lock:
            views = self._views(self._log_belief_PG)
            return self._next_step, self._beliefs(views, self._updates, self._last_actions)

    # --- step ------------------------------------------------------------------------------
    def step(
        self,
        observation: object,
        observed: Sequence[Observed] = (),
        expected_step: int | None = None,
    ) -> SessionStepResult:
        """Update the beliefs with `observed`, then act on `observation` (module docstring)."""
        with self._lock:
            t = self._next_step
            if expected_step is not None:
                if isinstance(expected_step, bool) or not isinstance(expected_step, int):
                    raise InvalidRequest(
                        "expected_step", f"expected an integer, got {brief(expected_step)}"
                    )
                if expected_step != t:
                    raise StepConflict(self.session_id, expected_step, t)
            checked = self._checked
            obs_1D, n_agents = self._observation(observation)
            indices = checked.inferred_indices
            n_actions = checked.runtime.domain.n_actions
            entries = check_observed(observed, indices, t, self._previous is not None, n_actions)
            log_belief_PG, updates, actions = self._updated(entries, obs_1D, indices, t)
            views = self._views(log_belief_PG)
            result = self._act(obs_1D, n_agents, views, t)
            # everything succeeded: commit
            self._log_belief_PG, self._updates, self._last_actions = log_belief_PG, updates, actions
            self._previous, self._previous_agents = obs_1D, n_agents
            self._next_step = t + 1
            self._last_views = (log_belief_PG, views)
            self._table_partners = self._expected_partners(entries, t, n_agents)
            if (
                result.budget_spent is not None
                and result.budget_total is not None
                and result.budget_value is not None
            ):
                self._budget = (result.budget_spent, result.budget_total, result.budget_value)
            beliefs = self._beliefs(views, updates, actions)
        return SessionStepResult(self.session_id, t, result, beliefs)

    def replace_settings(self, settings: SessionSettings) -> None:
        """New settings from the next step on (the `Episode` stream's settings message). A
        partner inferred before and after, in the same env, keeps its belief and counters (its
        new prior takes over through the forgetting term); others start from their prior. The
        step counter and the previous observation are kept (dropped if the env changes)."""
        checked = check_settings(settings)
        with self._lock:
            old = self._checked
            same_env = old.settings.env == settings.env
            old_rows = {old.settings.partners[i].index: r for r, i in enumerate(old.inferred)}
            log_belief_PG = checked.initial_PG.copy()
            updates = [0] * len(checked.inferred)
            for r, i in enumerate(checked.inferred):
                previous_row = old_rows.get(settings.partners[i].index)
                if same_env and previous_row is not None:
                    log_belief_PG[r] = self._log_belief_PG[previous_row]
                    updates[r] = self._updates[previous_row]
            self._checked, self._log_belief_PG, self._updates = checked, log_belief_PG, updates
            self._last_actions = [None] * len(checked.inferred)
            self._last_views = None
            self._table, self._table_partners = None, ()
            if not same_env:
                self._previous = None

    def prepare_next(self) -> bool:
        """Score the next step's evidence ahead (module docstring, "Scoring ahead"): call it
        once a step's answer is on its way. Whether a table was made; never raises for bad
        models or inputs (the next step runs the pass itself and reports them)."""
        with self._lock:
            t, partners = self._next_step, self._table_partners
            if not self.prefetch or not partners or self._previous is None:
                return False
            if self._table is not None and self._table[0] == t:
                return False
            settings = self._checked.settings
            goals = None  # pruning: the goals the next step's update scores, from this belief
            if settings.belief.prune_below > 0:
                rows = [self._checked.inferred_indices.index(p) for p in partners]
                goals = active_goals(self._log_belief_PG[rows], settings.belief.prune_below)
            try:
                table = likelihood_table(
                    self.engine.cache,
                    self._checked.runtime,
                    self._previous[0],
                    self._previous_agents,
                    partners,
                    alias=settings.alias,
                    versions=settings.versions,
                    temperature=settings.belief.temperature,
                    goals=goals,
                    noise=settings.belief.noise,
                )
            except EngineError:
                return False
            self._table = (t, table)
            return True

    # --- helpers ---------------------------------------------------------------------------
    def _expected_partners(
        self, entries: Sequence[Observed], t: int, n_agents: int
    ) -> tuple[int, ...]:
        """The partners whose actions step t + 1 will likely bring: those step t brought, in
        its order; after the first step, every inferred partner (the evidence starts then);
        none after a later step without evidence. Only partners the observation holds."""
        if entries:
            wanted: Sequence[int] = [e.index for e in entries]
        elif t == self._first_step:
            wanted = self._checked.inferred_indices
        else:
            return ()
        return tuple(index for index in wanted if index < n_agents)

    def _observation(self, observation: object) -> tuple[np.ndarray, int]:
        """The ego's observation as float32 (1, D), checked as /v1/act checks it, and the
        number of agents it holds."""
        if type(observation) is list:  # JSON's floats: one pass, when the checks would pass
            n_agents = self._checked.runtime.agents_by_obs_dim.get(len(observation))
            if n_agents is not None and all(
                type(v) is float and -FLOAT32_MAX <= v <= FLOAT32_MAX for v in observation
            ):  # finite, and finite in float32: the cast rounds as `check_observations`' does
                return np.array([observation], dtype=np.float32), n_agents
        try:
            obs = np.asarray(observation, dtype=np.float64)
        except (TypeError, ValueError):
            raise InvalidRequest("observation", "expected a list of numbers") from None
        if obs.ndim == 2 and obs.shape[0] == 1:
            obs = obs[0]
        if obs.ndim != 1:
            raise InvalidRequest(
                "observation", f"expected one row of numbers, got shape {obs.shape}"
            )
        try:
            return check_observations(obs[None, :], self._checked.runtime, max_batch=1)
        except EngineError as err:
            raise err.renamed("observation") from None

    def _updated(
        self, entries: Sequence[Observed], obs_1D: np.ndarray, indices: Sequence[int], t: int
    ) -> tuple[np.ndarray, list[int], list[int | None]]:
        """The beliefs, update counts and used actions after this step's evidence (copies)."""
        count = len(indices)
        actions_used: list[int | None] = [None] * count
        if not entries:
            return self._log_belief_PG, self._updates, actions_used
        assert self._previous is not None  # check_observed refuses entries without one
        checked, settings = self._checked, self._checked.settings
        actions = [e.action for e in entries]
        self._recover(entries, actions, obs_1D)
        partners = [e.index for e in entries]
        n_agents = self._previous_agents  # the actions are judged on the previous observation
        for j, index in enumerate(partners):
            if index >= n_agents:
                expected = f"1..{n_agents - 1}" if n_agents > 1 else "none (only the ego)"
                raise InvalidRequest(
                    f"observed[{j}].index",
                    f"{index} out of range: the previous observation holds {n_agents} "
                    f"agent(s), expected {expected}",
                )
        actions_E = np.array(actions, dtype=np.int64)
        rows = [indices.index(e.index) for e in entries]
        scored = self._scored_ahead(t, partners, actions_E)
        if settings.belief.prune_below > 0 and (scored is None or scored[1] is not None):
            log_belief_PG = self._log_belief_PG.copy()
            log_belief_PG[rows] = self._pruned(scored, partners, actions_E, rows)
            return log_belief_PG, *self._counted(rows, actions, actions_used)
        log_lik_EG = None if scored is None or scored[1] is not None else scored[0]
        if log_lik_EG is None:
            # = engine.goal_log_likelihoods(env, previous, partners, actions, ...) without its
            # checks: the settings were checked at creation, the observation and `observed` above
            log_lik_EG = checked_log_likelihoods(
                self.engine.cache,
                checked.runtime,
                self._previous[0],
                n_agents,
                partners,
                actions_E,
                alias=settings.alias,
                versions=settings.versions,
                temperature=settings.belief.temperature,
                noise=settings.belief.noise,
            )
        # = update_log_belief(log_belief_PG[rows], log_lik_EG, log_prior_PG[rows], belief)
        if rows == list(range(count)):  # every inferred partner, in order: no copies
            log_belief_PG = checked.update(self._log_belief_PG, log_lik_EG)
        else:
            log_belief_PG = self._log_belief_PG.copy()
            log_belief_PG[rows] = checked.update(log_belief_PG[rows], log_lik_EG, rows)
        return log_belief_PG, *self._counted(rows, actions, actions_used)

    def _counted(
        self, rows: Sequence[int], actions: Sequence[int | None], actions_used: list[int | None]
    ) -> tuple[list[int], list[int | None]]:
        """The update counts and used actions after updating `rows` with `actions`."""
        updates = list(self._updates)
        for row, action in zip(rows, actions, strict=True):
            updates[row] += 1
            actions_used[row] = action
        return updates, actions_used

    def _pruned(
        self,
        scored: tuple[np.ndarray, tuple[int, ...] | None] | None,
        partners: Sequence[int],
        actions_E: np.ndarray,
        rows: list[int],
    ) -> np.ndarray:
        """The new beliefs of `rows` with goal pruning (`policy.belief_prune`): the active
        goals' likelihoods (from the table scored ahead, else a pass over those goals only),
        the pruned update, and for each row whose bound exceeds `belief.prune_error` the other
        goals scored too and the exact update (the same numbers as without pruning)."""
        checked, settings = self._checked, self._checked.settings
        belief = settings.belief
        old_EG = self._log_belief_PG[rows]
        if scored is not None and scored[1] is not None:
            log_lik_EA, active = scored[0], np.array(scored[1], dtype=np.intp)
        else:
            active = active_goals(old_EG, belief.prune_below)
            log_lik_EA = self._likelihoods(partners, actions_E, active)
        step = checked.update.pruned(old_EG, log_lik_EA, active, rows)
        new_EG = step.log_belief_EG
        over = np.flatnonzero(~(step.bound_E <= belief.prune_error))  # inf and NaN too
        stats = self.engine.stats
        if len(active) < len(checked.goals):  # goals were skipped
            stats.pruned_updates += len(rows) - len(over)
        if len(over):
            stats.pruned_rescored += len(over)
            rest = np.setdiff1d(np.arange(len(checked.goals)), active)
            log_lik_EG = np.empty((len(over), len(checked.goals)))
            log_lik_EG[:, active] = log_lik_EA[over]
            chosen = over.tolist()
            log_lik_EG[:, rest] = self._likelihoods(
                [partners[e] for e in chosen], actions_E[over], rest
            )
            new_EG[over] = checked.update(old_EG[over], log_lik_EG, [rows[e] for e in chosen])
        return new_EG

    def _likelihoods(
        self, partners: Sequence[int], actions_E: np.ndarray, goals: np.ndarray
    ) -> np.ndarray:
        """(E, len(goals)) log-likelihoods of the partners' actions on the previous
        observation under the task networks of `goals` (arguments checked by the step)."""
        assert self._previous is not None
        settings = self._checked.settings
        return checked_log_likelihoods(
            self.engine.cache,
            self._checked.runtime,
            self._previous[0],
            self._previous_agents,
            partners,
            actions_E,
            alias=settings.alias,
            versions=settings.versions,
            temperature=settings.belief.temperature,
            goals=goals,
            noise=settings.belief.noise,
        )

    def _scored_ahead(
        self, t: int, partners: Sequence[int], actions_E: np.ndarray
    ) -> tuple[np.ndarray, tuple[int, ...] | None] | None:
        """The log-likelihoods from the table `prepare_next` made for step t and the goals it
        scored (None: every goal), or None (no table, another step's, other partners, or an
        alias moved since: `LikelihoodTable.pick`)."""
        if self._table is None or self._table[0] != t:
            return None
        settings = self._checked.settings
        group = task_group(
            self.engine.cache, self._checked.runtime, settings.alias, settings.versions
        )
        table = self._table[1]
        log_lik_EG = table.pick(group, partners, actions_E)
        if log_lik_EG is None:
            return None
        self.engine.stats.likelihood_tables_used += 1
        return log_lik_EG, table.goals

    def _recover(
        self, entries: Sequence[Observed], actions: list[int | None], obs_1D: np.ndarray
    ) -> None:
        """Fill the actions sent as None from the previous and current observations."""
        missing = [j for j, a in enumerate(actions) if a is None]
        if not missing:
            return
        assert self._previous is not None
        field = f"observed[{missing[0]}].action"
        if self._previous.shape != obs_1D.shape:
            raise InvalidRequest(
                field,
                f"cannot recover the action: the observation's length changed from "
                f"{self._previous.shape[1]} to {obs_1D.shape[1]} since the previous step; send it",
            )
        try:
            recovered = self.engine.recover_partner_actions(
                self._checked.settings.env,
                self._previous[0],
                obs_1D[0],
                [entries[j].index for j in missing],
            )
        except InvalidRequest as err:
            raise err.renamed(field) from None
        for j, action in zip(missing, recovered, strict=True):
            actions[j] = int(action)

    def _views(self, log_belief_PG: np.ndarray) -> list[BeliefView]:
        """Each inferred partner's blend distribution and summary (`belief_views`); a belief
        the last step committed (a step without evidence) reuses that step's."""
        last = self._last_views
        if last is not None and last[0] is log_belief_PG:
            return last[1]
        settings = self._checked.settings
        return belief_views(
            log_belief_PG,
            self._checked.goals,
            TOP_GOALS,
            settings.blend_mass,
            settings.blend_max_goals,
            settings.belief.prune_below,
            settings.belief.prune_error,
        )

    def _act(self, obs_1D: np.ndarray, n_agents: int, views: list[BeliefView], t: int) -> ActResult:
        """`engine.act` of the request with each inferred partner's `goal_probs` =
        `blend_goal_probs` of its belief. The request's parts were checked (settings at
        creation, the observation in `step`, the partner indices here) and the distribution is
        built as `check_request` builds it from such a mapping (renormalised by its sum), so
        the engine takes it as checked (`act_checked`): the same result, without a per-goal
        check of 35 numbers the belief produced."""
        checked, settings = self._checked, self._checked.settings
        partners, row = [], 0
        for i, (partner, fixed) in enumerate(
            zip(settings.partners, checked.announced, strict=True)
        ):
            if not 1 <= partner.index < n_agents:  # the field's name only for the error
                check_partner_index(partner.index, n_agents, f"partners[{i}].index")
            if fixed is None:  # inferred
                kept, probs = views[row].blend_goals, views[row].blend_probs
                goals = checked.goals
                if len(kept) < len(goals):
                    goals = tuple(goals[g] for g in kept)
                total = math.fsum(probs)
                fixed = CheckedPartner(partner.index, goals, tuple([p / total for p in probs]))
                row += 1
            partners.append(fixed)
        # the partners are in `ready` (`act_checked` reads them, and the observation, there);
        # without a seed the request is the same at every step
        request = checked.act_request
        if settings.seed is not None:
            request = ActRequest(
                env=settings.env,
                ego_goal=settings.ego_goal,
                observations=obs_1D,
                method=settings.method,
                temperature=settings.temperature,
                regret_bound=settings.regret_bound,
                budget=settings.budget,
                seed=settings.seed + t,
                alias=settings.alias,
                versions=settings.versions,
            )
        # the episode's budget state, carried as a client of /v1/act would
        spent_1: np.ndarray | None = None
        budget_1: np.ndarray | None = None
        value_1: np.ndarray | None = None
        if self._budget is not None:
            spent_1, budget_1, value_1 = (np.array([x]) for x in self._budget)
        ready = CheckedRequest(
            checked.runtime, obs_1D, n_agents, tuple(partners), spent_1, budget_1, value_1
        )
        try:
            return self.engine.act_checked(request, ready)[0]
        except EngineError as err:
            if err.field is not None and err.field.startswith("observations"):
                raise err.renamed("observation") from None
            raise

    def _beliefs(
        self, views: list[BeliefView], updates: Sequence[int], actions: Sequence[int | None]
    ) -> tuple[PartnerBelief, ...]:
        return tuple(
            PartnerBelief(index, tuple(view.top), view.entropy, actions[r], updates[r])
            for r, (index, view) in enumerate(
                zip(self._checked.inferred_indices, views, strict=True)
            )
        )
