"""Can the ego's own task network stand in for the goal oracle? A probe of AAIL-B's R2 and R4
without the environment's answers.

    python -m evaluation.partners.task_q_oracle --store-url URL [--alias production]
        [--goals all] [--states 4000] [--seed 0] [--out reports/partners/draw6262/task_q_oracle.md]

AAIL-B blends only where the ego's goal is reached (R2) and only among the actions that keep it
(R4), both answered by the particle domain (`Domain.goal_reached`, `Domain.goal_kept`). Without
them it strands its ego (`reports/partners/draw6262/no_oracle/`). The ego's task network is the
one model of its own goal the server holds; this probe measures whether its Q-values tell the
actions that keep the target from those that lose it, on states where the answer matters.

States: per goal, `--states` egos drawn uniformly in the goal's target area widened by
`MARGIN` on each side (clipped to the world), with a speed up to the cap in a random direction
(30 % at rest), beside a partner drawn anywhere; the truth is the domain's `goal_kept` for each
action. Reported, pooled over the goals:

- boundary rows (some actions keep the target, some lose it): how often the network's best
  action is one that loses it;
- a threshold on Q itself, Q(s, a) >= θ as "keeps": the share of the actions it selects that
  lose the target, and the share of keeping actions it selects (the task reward holds the
  partner's distance to the goal's influence area too, so Q has no fixed level for "reached");
- the spread of Q over the actions (max - min) where every action keeps the target and where
  none does: a relative rule (R1 itself) needs the first well below the second.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from envs.particle.domain import ParticleDomain
from envs.particle.goals import GOAL_IDS, TARGET_BOXES_G4, goal_index
from envs.particle.world import MAX_SPEED
from evaluation.command_line import portable_command
from model_store.defaults import open_store
from model_store.store import ModelStore
from trainer.zoo import load_task_nets

MARGIN = 0.15  # how far outside the target area egos are drawn (three full-speed steps)
REST_SHARE = 0.3  # egos drawn at rest
THRESHOLDS = (-0.1, 0.0, 0.1)  # Q levels tried as "keeps the target"


@dataclass(frozen=True)
class Probe:
    """Pooled over the goals (module docstring)."""

    goals: int
    states: int
    boundary_rows: int
    best_loses: int  # boundary rows whose best action loses the target
    thresholds: tuple[tuple[float, float, float], ...]  # (θ, share losing, share of keeps kept)
    spread_all_keep: tuple[float, float]  # median, 90th percentile
    spread_none_keep: tuple[float, float]  # 10th percentile, median


def probe(
    store: ModelStore, alias: str, states: int, seed: int, goals: tuple[str, ...] = GOAL_IDS
) -> Probe:
    """The measures of the module docstring over the task networks of `goals` at `alias`."""
    domain = ParticleDomain()
    nets, _ = load_task_nets(store, "particle", goals, alias)
    rng = np.random.default_rng(seed)
    q_rows, kept_rows = [], []
    for g, goal in enumerate(goals):
        box = TARGET_BOXES_G4[goal_index(goal)]
        low, high = np.array([box[0], box[2]]) - MARGIN, np.array([box[1], box[3]]) + MARGIN
        ego_xy = np.clip(rng.uniform(low, high, (states, 2)), 0.0, 1.0)
        speed = rng.uniform(0.0, MAX_SPEED, states) * (rng.random(states) >= REST_SHARE)
        angle = rng.uniform(0.0, 2 * np.pi, states)
        ego_v = np.stack([np.cos(angle), np.sin(angle)], axis=1) * speed[:, None]
        partner = np.concatenate(
            [rng.uniform(0.0, 1.0, (states, 2)), rng.uniform(-0.35, 0.35, (states, 2))], axis=1
        )
        obs = np.concatenate([ego_xy, ego_v, partner], axis=1)
        views = torch.zeros(len(goals), states, domain.pair_obs_dim)
        views[g] = torch.from_numpy(domain.task_views(obs, 2)[:, 0]).float()
        with torch.no_grad():
            q_rows.append(nets(views)[g].double().numpy())
        kept_rows.append(np.asarray(domain.goal_kept(obs, 2, goal), dtype=bool))
    q, kept = np.concatenate(q_rows), np.concatenate(kept_rows)
    boundary = kept.any(axis=1) & ~kept.all(axis=1)
    best = q.argmax(axis=1)
    best_loses = int((~kept[np.arange(len(q)), best] & boundary).sum())
    thresholds = []
    for theta in THRESHOLDS:
        chosen = q >= theta
        losing = float((chosen & ~kept).sum() / max(int(chosen.sum()), 1))
        keeps = float((chosen & kept).sum() / max(int(kept.sum()), 1))
        thresholds.append((theta, losing, keeps))
    spread = q.max(axis=1) - q.min(axis=1)
    all_keep, none_keep = spread[kept.all(axis=1)], spread[~kept.any(axis=1)]
    return Probe(
        goals=len(goals),
        states=len(q),
        boundary_rows=int(boundary.sum()),
        best_loses=best_loses,
        thresholds=tuple(thresholds),
        spread_all_keep=(float(np.median(all_keep)), float(np.percentile(all_keep, 90))),
        spread_none_keep=(float(np.percentile(none_keep, 10)), float(np.median(none_keep))),
    )


def to_markdown(result: Probe, command: str) -> str:
    lines = [
        "# Can the task network stand in for the goal oracle?",
        "",
        f"Generated by `{command}` (`evaluation/partners/task_q_oracle.py` says what is drawn).",
        f"{result.goals} goals, {result.states:,} states; the truth is the particle domain's "
        "`goal_kept`.",
        "",
        "| measure | value |",
        "|---|---|",
        f"| boundary rows (some actions keep the target, some lose it) | {result.boundary_rows:,} |",
        f"| of them, the task network's best action loses the target | {result.best_loses:,} "
        f"({result.best_loses / max(result.boundary_rows, 1):.1%}) |",
    ]
    for theta, losing, keeps in result.thresholds:
        lines.append(
            f'| Q ≥ {theta:+.1f} as "keeps": share of the chosen actions that lose the target; '
            f"share of the keeping actions chosen | {losing:.1%}; {keeps:.1%} |"
        )
    lines += [
        "| spread of Q over the actions where every action keeps the target: median, 90th "
        f"percentile | {result.spread_all_keep[0]:.3f}, {result.spread_all_keep[1]:.3f} |",
        "| the same where no action keeps it: 10th percentile, median | "
        f"{result.spread_none_keep[0]:.3f}, {result.spread_none_keep[1]:.3f} |",
        "",
    ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--store-url", required=True)
    parser.add_argument("--alias", default="production")
    parser.add_argument("--goals", default="all", help="'all' or comma-separated goal ids")
    parser.add_argument("--states", type=int, default=4000, help="states per goal")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=None, help="markdown file (else stdout)")
    args = parser.parse_args(argv)
    if args.states < 1:
        parser.error("--states: expected >= 1")
    goals = GOAL_IDS if args.goals == "all" else tuple(g.strip() for g in args.goals.split(","))
    unknown = [g for g in goals if g not in GOAL_IDS]
    if unknown:
        parser.error(f"--goals: not particle goals: {', '.join(unknown)}")
    with open_store(args.store_url) as store:
        result = probe(store, args.alias, args.states, args.seed, goals)
    words = ["python", "-m", "evaluation.partners.task_q_oracle", "--store-url", args.store_url]
    words += ["--alias", args.alias, "--goals", args.goals, "--states", str(args.states)]
    words += ["--seed", str(args.seed)]
    command = portable_command(words)
    text = to_markdown(result, command)
    if args.out is None:
        print(text)
    else:
        args.out.write_text(text)


if __name__ == "__main__":
    main()
