"""The cooking experiment of the paper (§4.4, Fig. 9): AAIL vs SL for the left cook of Fig. 8.

The coexistence kitchen (`envs.cooking.layouts`): the LEFT cook (agent 0) cooks
TomatoLettuceSalad, which needs no help; the RIGHT cook (agent 1) cooks CarrotBanana, which needs
the carrot that only the left cook can reach (over the pass-through counter). The left cook is
served by the inference engine with `aail` (its task network blended with the impact network of
the right cook's announced recipe) or `sl` (the task network alone); the right cook follows its
*partner population's* task policy (`sl`, alias `partners`: trained with another seed, never with
the left cook's networks), or the scripted cook when that network is not registered (recorded in
`right_cook`). Episodes end when both dishes are served or after 400 steps (the paper's limit).

| array          | shape     | meaning                                                   |
|----------------|-----------|-----------------------------------------------------------|
| `served_MEN`   | (M, E, 2) | agent n's dish served in episode e under method m         |
| `steps_MEN`    | (M, E, 2) | the step of that dish, -1 without one                     |
| `returns_MEN`  | (M, E, 2) | unshaped returns (+20 dish, -0.01 per waiting step)       |

Pairing (common random numbers): every episode starts from the layout's start, and agent n in
episode e at step t samples its action by inverse CDF from the same uniform u[t, e, n] under
every method, so AAIL and SL differ by policy, not by sampling luck; the paired test of the
completion ratios is McNemar's. All M x E episodes step in one batched kitchen; per step there is
one `engine.act` per method (its active rows) and one for the right cooks of every method.

The policies come from a `PolicyBackend` (`evaluation.backend`): the inference engine in-process
(an `InferenceEngine` is wrapped in one) or a running server, so `coexist eval --suite cooking
--server URL` plays the same episodes through REST or gRPC. `evaluation.cooking.report` writes
the files of `reports/cooking` and the cooking section of the paper report.

`temperature` (default None: the engine serves at the task network's training α) sets the left
cook's Boltzmann temperature for every method (in-process or sent to the server alike).
It is a sensitivity knob, not part of the paper's protocol: at α a blended policy that prefers a
no-op (walking into a counter that takes nothing) repeats it forever, since the state does not
change; a warmer policy walks out of such loops.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from envs.cooking import (
    DISH_REWARD,
    TIME_PENALTY,
    BatchedCookingWorld,
    CookingState,
    ScriptedCook,
    render_frame,
    save_gif,
    scripted_actions,
)
from evaluation.backend import Answer, EngineBackend, ModelRecord, PolicyBackend
from evaluation.config import METHOD_LABELS
from evaluation.stats import MeanSE, holm, mcnemar_p, mean_se, paired_ci, rank_biserial
from model_store.store import ModelStore
from services.engine import ActRequest, InferenceEngine, PartnerSpec

LAYOUT = "coexistence"
RECIPES = ("TomatoLettuceSalad", "CarrotBanana")  # left cook (controlled), right cook
AGENT_LABELS = ("left cook (AAIL / SL)", "right cook (partner)")
PAPER_FIG9 = (
    "AAIL completes its own dish ~4 % less often than SL; the partner's completion is much higher"
)


@dataclass
class CookingResults:
    """Outcomes of `evaluate_cooking` (module docstring)."""

    methods: tuple[str, ...]
    seed: int
    max_steps: int
    right_cook: str  # what controlled the right cook
    served_MEN: np.ndarray
    steps_MEN: np.ndarray
    returns_MEN: np.ndarray
    models: dict[str, list[str]] = field(default_factory=dict)  # method -> "name/version"
    trajectory: list[CookingState] = field(default_factory=list)  # the recorded episode
    temperature: float | None = None  # the left cook's Boltzmann temperature (None: served α)

    @property
    def episodes(self) -> int:
        return int(self.served_MEN.shape[1])

    def completion(self, method: str, agent: int) -> MeanSE:
        """Dish completion ratio of `agent` under `method`, mean ± standard error."""
        return mean_se(self.served_MEN[self.methods.index(method), :, agent].astype(float).tolist())

    def mean_return(self, method: str, agent: int) -> MeanSE:
        return mean_se(self.returns_MEN[self.methods.index(method), :, agent].tolist())

    def steps_to_dish(self, method: str, agent: int) -> float:
        m = self.methods.index(method)
        served = self.served_MEN[m, :, agent]
        return float(self.steps_MEN[m, served, agent].mean()) if served.any() else float("nan")

    def mcnemar(self, agent: int, a: str = "aail", b: str = "sl") -> float:
        """Paired exact McNemar p of the completion of `agent` under methods a and b."""
        ia, ib = self.methods.index(a), self.methods.index(b)
        return mcnemar_p(self.served_MEN[ia, :, agent], self.served_MEN[ib, :, agent])

    def _temperature(self) -> str:
        return "= the task network's α" if self.temperature is None else f"{self.temperature:g}"

    def to_markdown(self) -> str:
        lines = [
            f"Cooking coexistence kitchen (paper Fig. 8/9): {self.episodes} episodes per method, "
            f"at most {self.max_steps} steps, seed {self.seed}. Left cook: {RECIPES[0]} "
            f"(controlled, temperature {self._temperature()}); right cook: {RECIPES[1]} "
            f"({self.right_cook}).",
            "",
            "| method | left: dish completion | left: return | left: steps to dish "
            "| right: dish completion | right: return | right: steps to dish |",
            "|---|---|---|---|---|---|---|",
        ]
        for method in self.methods:
            cells = []
            for agent in (0, 1):
                c, r = self.completion(method, agent), self.mean_return(method, agent)
                steps = self.steps_to_dish(method, agent)
                cells += [
                    f"{c.mean:.2f} ± {c.se:.2f}",
                    f"{r.mean:.2f} ± {r.se:.2f}",
                    "-" if np.isnan(steps) else f"{steps:.1f}",
                ]
            lines.append(f"| {METHOD_LABELS.get(method, method)} | " + " | ".join(cells) + " |")
        compared = [
            m
            for m in ("aail_budget", "aail_bounded", "aail")
            if m in self.methods and "sl" in self.methods
        ]
        if compared:
            lines.append("")
        # the kitchen's comparisons with SL, both cooks, are one family for Holm's correction
        keys = [(m, agent) for m in compared for agent in (0, 1)]
        adjusted = dict(zip(keys, holm([self.mcnemar(a, m) for m, a in keys]), strict=True))
        for m in compared:
            shown = []
            for agent, cook in ((0, "left"), (1, "right")):
                x = self.served_MEN[self.methods.index(m), :, agent].astype(float)
                y = self.served_MEN[self.methods.index("sl"), :, agent].astype(float)
                shown.append(
                    f"{cook} cook {float(np.mean(x - y)):+.2f}, 95 % CI {paired_ci(x, y)}, "
                    f"r = {rank_biserial(x, y):+.2f} (McNemar p = {self.mcnemar(agent, m):.3g}, "
                    f"Holm p = {adjusted[(m, agent)]:.3g})"
                )
            lines.append(f"{METHOD_LABELS[m]} - SL: " + "; ".join(shown) + ".")
        if compared:
            lines.append(f"Paper (AAIL - SL): {PAPER_FIG9}.")
        if self.models:
            used = "; ".join(f"{m}: {', '.join(v)}" for m, v in self.models.items())
            lines += ["", f"Networks: {used}."]
        return "\n".join(lines)


def _inverse_cdf(probs_BA: np.ndarray, u_B: np.ndarray) -> np.ndarray:
    """The first action whose cumulative probability exceeds u (a p = 0 action never)."""
    cdf_BA = np.cumsum(probs_BA, axis=1)
    picked = (cdf_BA <= u_B[:, None] * cdf_BA[:, -1:]).sum(axis=1)
    return np.minimum(picked, probs_BA.shape[1] - 1)


_ROLE_ORDER = {"task": 0, "impact": 1, "joint": 2}


def _answer(backend: PolicyBackend, request: ActRequest) -> tuple[Answer, list[str]]:
    answer = backend.answer(request)
    return answer, [f"{m.name}/{m.version}" for m in sorted(answer.models, key=_model_order)]


def _model_order(record: ModelRecord) -> tuple[int, str]:
    return _ROLE_ORDER.get(record.role, 3), record.name


def _partner_request(obs_BD: np.ndarray, alias: str) -> ActRequest:
    return ActRequest(
        env="cooking", ego_goal=RECIPES[1], observations=obs_BD, method="sl", alias=alias
    )


def evaluate_cooking(
    policies: InferenceEngine | PolicyBackend,
    store: ModelStore | None = None,
    *,
    episodes: int = 100,
    seed: int = 0,
    methods: Sequence[str] = ("aail_bounded", "aail_budget", "aail", "sl"),
    max_steps: int = 400,
    alias: str = "production",
    partner_alias: str = "partners",
    record: str | None = "aail_bounded",
    temperature: float | None = None,
    progress: Callable[[int, int], None] | None = None,
    scripted_partner: bool = False,
) -> CookingResults:
    """Run `episodes` paired episodes per method (module docstring); `record` keeps the states
    of the first episode of that method (for `save_cooking_gif`). `policies`: an engine or any
    `PolicyBackend`; the left cook's networks resolve by `alias`, the right cook's by
    `partner_alias` (`scripted_partner`: the scripted cook even where a network is
    registered). `store` is not needed by the rollout itself (the backend reads it); it is
    accepted for the report's uniform call. An aail_budget cook carries its episode's budget
    from step to step, as a client of `/v1/act` does. `progress(step, running episodes)` after each step.
    A LookupError, before any episode, when the left cook's networks are not served."""
    del store
    if episodes < 1 or max_steps < 1:
        raise ValueError(f"episodes, max_steps: expected >= 1, got {episodes}, {max_steps}")
    backend = EngineBackend(policies) if isinstance(policies, InferenceEngine) else policies
    methods = tuple(methods)
    n_methods, n_rows = len(methods), len(methods) * episodes
    world = BatchedCookingWorld(LAYOUT, np.array([RECIPES] * n_rows), max_steps=max_steps)
    u_TEN = np.random.default_rng(np.random.SeedSequence([seed, 9])).random(
        (max_steps, episodes, 2)
    )
    left_request = ActRequest(
        env="cooking",
        ego_goal=RECIPES[0],
        observations=world.observe()[:1, 0],
        partners=(PartnerSpec(index=1, goal=RECIPES[1]),),
        alias=alias,
    )
    if not backend.has_models(left_request):
        raise LookupError(
            f"the left cook's networks are not served: cooking/task/{RECIPES[0]} and "
            f"cooking/impact/{RECIPES[1]} at alias {alias!r} ({backend.description}); train them "
            "with `coexist train zoo --env cooking --goals TomatoLettuceSalad,CarrotBanana`"
        )
    learned = not scripted_partner and backend.has_models(
        _partner_request(world.observe()[:1, 1], partner_alias)
    )
    if learned:
        right_cook = f"learned task network, alias {partner_alias!r}"
    else:
        right_cook = "scripted cook (no partner-population network registered)"
    scripted = [None, ScriptedCook(RECIPES[1])]

    shape = (n_methods, episodes, 2)
    served, steps, returns = np.zeros(shape, bool), np.full(shape, -1), np.zeros(shape)
    models: dict[str, list[str]] = {}
    record_row = methods.index(record) * episodes if record in methods else None
    trajectory = [] if record_row is None else [world.state.select(record_row)]
    obs_BND = world.observe()
    # aail_budget's episode state (S, B, V)
    spent_B, total_B, value_B = np.zeros(n_rows), np.zeros(n_rows), np.zeros(n_rows)
    for t in range(max_steps):
        active_B = ~np.all(served.reshape(n_rows, 2), axis=1)
        if not active_B.any():
            break
        actions_BN = np.zeros((n_rows, 2), dtype=np.int64)
        u_BN = np.tile(u_TEN[t], (n_methods, 1))
        for m, method in enumerate(methods):
            rows = np.flatnonzero(active_B[m * episodes : (m + 1) * episodes]) + m * episodes
            if rows.size == 0:
                continue
            request = ActRequest(
                env="cooking",
                ego_goal=RECIPES[0],
                observations=obs_BND[rows, 0],
                partners=(PartnerSpec(index=1, goal=RECIPES[1]),),
                method=method,  # type: ignore[arg-type]
                temperature=temperature,
                seed=seed,
                alias=alias,
            )
            if method == "aail_budget" and t > 0:  # the first step sends no state
                request = replace(
                    request,
                    budget_spent=spent_B[rows],
                    budget_total=total_B[rows],
                    budget_value=value_B[rows],
                )
            answer, models[method] = _answer(backend, request)
            probs_BA = answer.probs_BA
            if (
                answer.budget_spent_B is not None
                and answer.budget_total_B is not None
                and answer.budget_value_B is not None
            ):
                spent_B[rows], total_B[rows] = answer.budget_spent_B, answer.budget_total_B
                value_B[rows] = answer.budget_value_B
            actions_BN[rows, 0] = _inverse_cdf(probs_BA, u_BN[rows, 0])
        rows = np.flatnonzero(active_B)
        if right_cook.startswith("learned"):
            partner, models["partner"] = _answer(
                backend, _partner_request(obs_BND[rows, 1], partner_alias)
            )
            probs_BA = partner.probs_BA
            actions_BN[rows, 1] = _inverse_cdf(probs_BA, u_BN[rows, 1])
        else:
            actions_BN[:, 1] = scripted_actions(world.layout, world.state, scripted)[:, 1]
        waiting_BN = ~world.state.delivered
        result = world.step(actions_BN)
        delivered_MEN = world.state.delivered.reshape(shape)
        first = delivered_MEN & ~served
        steps[first] = t + 1
        served |= delivered_MEN
        live_MEN = active_B.reshape(n_methods, episodes, 1)
        unshaped = DISH_REWARD * first - TIME_PENALTY * waiting_BN.reshape(shape)
        returns += np.where(live_MEN, unshaped, 0.0)
        obs_BND = result.next_obs_BND
        if record_row is not None and active_B[record_row]:
            trajectory.append(world.state.select(record_row))
        if progress is not None:
            progress(t + 1, int((~np.all(served.reshape(n_rows, 2), axis=1)).sum()))
    return CookingResults(
        methods,
        seed,
        max_steps,
        right_cook,
        served,
        steps,
        returns,
        models,
        trajectory,
        temperature,
    )


def plot_cooking(results: CookingResults, path: str | Path) -> Path:
    """Bar plot of the dish completion ratios with standard errors (paper Fig. 9)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 3.6))
    width = 0.8 / len(results.methods)
    for m, method in enumerate(results.methods):
        stats = [results.completion(method, agent) for agent in (0, 1)]
        xs = np.arange(2) + (m - (len(results.methods) - 1) / 2) * width
        bars = ax.bar(
            xs,
            [s.mean for s in stats],
            width,
            yerr=[s.se for s in stats],
            capsize=4,
            label=method.upper(),
        )
        ax.bar_label(bars, labels=[f"{s.mean:.2f}" for s in stats], padding=2, fontsize=8)
    ax.set_xticks(
        np.arange(2), [f"{label}\n{r}" for label, r in zip(AGENT_LABELS, RECIPES, strict=True)]
    )
    ax.set_ylim(0, 1.12)
    ax.set_ylabel("dish completion ratio")
    ax.set_title(f"Cooking coexistence, {results.episodes} runs (± standard error)")
    ax.legend(title="left cook", loc="upper right")
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return path


def save_cooking_gif(results: CookingResults, path: str | Path, fps: int = 6) -> Path:
    """A GIF of the recorded episode (`evaluate_cooking(record=...)`)."""
    if not results.trajectory:
        raise ValueError("results: no recorded episode (evaluate_cooking(record=None)?)")
    world = BatchedCookingWorld(LAYOUT, np.array([RECIPES]))
    frames = [render_frame(world.layout, state, RECIPES) for state in results.trajectory]
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return save_gif(frames, path, fps=fps)
