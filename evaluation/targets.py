"""What the product promises on goal pairs nobody tuned on, as checks with fixed thresholds.

The paper's claims (`evaluation.paper.claims`) are judged on its hand-picked scenarios. These targets
are judged on the strict pair classes and random five-agent goal sets (`evaluation.paper.pairs`), for
the blend the server uses by default (AAIL-B, `policy.regret_bound`) and, beside it with the same
thresholds, for the paper-exact AAIL. They were fixed before the run they judge.

| target | class              | check                                                              |
|--------|--------------------|--------------------------------------------------------------------|
| T1     | non-aligned pairs  | ego success >= 0.99 over all episodes                              |
|        |                    | no stuck episode (the ego never ends outside its target)           |
|        |                    | median own-return regret vs SL over pairs <= 10 %                 |
|        |                    | team return not below SL's: mean per-pair difference >= 0, or not |
|        |                    | significant (Wilcoxon p >= 0.05)                                   |
|        |                    | NAIL, the ablation, still fails: its ego success <= 0.75           |
| T2     | aligned pairs      | team return >= SL's within 2 % in >= 95 % of the pairs             |
|        | room to help       | team return > SL's over the pairs whose target strictly contains   |
|        |                    | the influence area: mean difference > 0, Wilcoxon p < 0.01         |
| T3     | five-agent sets    | team return >= SL's in every set                                   |
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from evaluation.config import METHOD_LABELS
from evaluation.paper.claims import Check
from evaluation.paper.pairs import UnitGroup

MIN_SUCCESS = 0.99
MAX_MEDIAN_REGRET = 0.10
NAIL_FAILS_BELOW = 0.75
TEAM_WITHIN_SHARE = 0.95
ALPHA_HELP = 0.01
ALPHA_HARM = 0.05


@dataclass(frozen=True)
class Target:
    key: str  # "T1", ...
    method: str
    title: str
    checks: tuple[Check, ...]

    @property
    def verdict(self) -> str:
        if not self.checks:
            return "not tested"
        return "met" if all(c.passed for c in self.checks) else "not met"


def _p(p: float) -> str:
    return f"p = {p:.2g}"


def non_aligned_target(group: UnitGroup, method: str) -> Target:
    row, name = group.rows[method], METHOD_LABELS[method]
    success = row.means["ego_success"].mean
    checks = [
        Check(
            f"{name} ego success >= {MIN_SUCCESS:g}",
            success >= MIN_SUCCESS,
            f"{success:.3f} over {row.episodes:,} episodes of {row.n_units} pairs",
        ),
        Check(
            "no stuck episode",
            row.stuck_episodes == 0,
            f"{row.stuck_episodes} stuck episodes in {row.units_with_stuck} pairs",
        ),
        Check(
            f"median own-return regret vs SL <= {MAX_MEDIAN_REGRET:.0%}",
            row.regret_median <= MAX_MEDIAN_REGRET,
            f"median {row.regret_median:.1%}, mean {row.regret_mean:.1%}",
        ),
    ]
    team = group.test(method, "sl", "team")
    if team is not None:
        ok = team.diff.mean >= 0 or team.p >= ALPHA_HARM
        checks.append(
            Check(
                "team return not below SL's",
                ok,
                f"{name} − SL = {team.diff} per pair ({_p(team.p)}, higher in {team.better:.0%})",
            )
        )
    if "nail" in group.rows:
        nail = group.rows["nail"].means["ego_success"].mean
        checks.append(
            Check(
                f"NAIL still fails (ego success <= {NAIL_FAILS_BELOW:g})",
                nail <= NAIL_FAILS_BELOW,
                f"NAIL ego success {nail:.2f}",
            )
        )
    return Target("T1", method, "non-aligned pairs: keeps its own task", tuple(checks))


def aligned_target(aligned: UnitGroup, room: UnitGroup | None, method: str) -> Target:
    row, name = aligned.rows[method], METHOD_LABELS[method]
    checks = [
        Check(
            f"team >= SL − 2 % in >= {TEAM_WITHIN_SHARE:.0%} of aligned pairs",
            row.team_within_share >= TEAM_WITHIN_SHARE,
            f"{row.team_within_share:.0%} of {row.n_units} pairs ({row.team_above_share:.0%} "
            "strictly above SL)",
        ),
    ]
    test = room.test(method, "sl", "team") if room is not None else None
    if test is None:
        checks.append(Check("team > SL where there is room to help", False, "no such pair ran"))
    else:
        checks.append(
            Check(
                f"team > SL where there is room to help (p < {ALPHA_HELP:g})",
                test.diff.mean > 0 and test.p < ALPHA_HELP,
                f"{name} − SL = {test.diff} over {test.n_units} pairs ({_p(test.p)}, higher "
                f"in {test.better:.0%})",
            )
        )
    return Target("T2", method, "aligned pairs: helps where it can", tuple(checks))


def five_agent_target(group: UnitGroup, method: str) -> Target:
    name = METHOD_LABELS[method]
    having = [u for u in group.units if method in u.by_method and "sl" in u.by_method]
    below = [u for u in having if u.by_method[method]["team"] < u.by_method["sl"]["team"]]
    worst = min(
        (u.by_method[method]["team"] - u.by_method["sl"]["team"] for u in having), default=0.0
    )
    check = Check(
        "team return >= SL's in every five-agent goal set",
        bool(having) and not below,
        f"{name} below SL in {len(below)} of {len(having)} sets (worst {worst:+.2f})",
    )
    return Target("T3", method, "five agents, random goal sets", (check,))


def targets_of(groups: Mapping[str, UnitGroup], methods: tuple[str, ...]) -> list[Target]:
    """T1-T3 for each of `methods` that ran (module docstring); groups that did not run are
    left out."""
    targets = []
    for method in methods:
        if "non_aligned" in groups and method in groups["non_aligned"].rows:
            targets.append(non_aligned_target(groups["non_aligned"], method))
        if "aligned" in groups and method in groups["aligned"].rows:
            targets.append(aligned_target(groups["aligned"], groups.get("room_to_help"), method))
        if "five_agents" in groups and method in groups["five_agents"].rows:
            targets.append(five_agent_target(groups["five_agents"], method))
    return targets
