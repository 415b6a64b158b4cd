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
|        |                    | team return not below SL's: paired TOST over pairs, margin 2 % of |
|        |                    | SL's mean team return, H0⁻ (worse by the margin or more) rejected |
|        |                    | at 0.05 after Holm's correction over the methods judged           |
|        |                    | NAIL, the ablation, still fails: its ego success <= 0.75           |
| T2     | aligned pairs      | team return >= SL's within 2 % in >= 95 % of the pairs             |
|        | room to help       | team return > SL's over the pairs whose target strictly contains   |
|        |                    | the influence area: mean difference > 0, Wilcoxon p < 0.01, the p  |
|        |                    | Holm-adjusted within that class's family (`pairs.class_family`)    |
| T3     | five-agent sets    | team return >= SL's in every set                                   |

"Not below SL's" was first judged as "mean difference >= 0 or Wilcoxon p >= 0.05", which a
class with few or noisy pairs passes for want of evidence; the TOST asks for evidence that the
loss, if any, is smaller than the margin. Families for Holm's correction: T1's non-inferiority
tests, one per method judged (`targets_of`); T2's test, within its class's table of tests.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from evaluation.config import METHOD_LABELS
from evaluation.paper.claims import Check
from evaluation.paper.pairs import UnitGroup, class_family, family_test
from evaluation.stats import Tost, fmt_p, holm

MIN_SUCCESS = 0.99
MAX_MEDIAN_REGRET = 0.10
NAIL_FAILS_BELOW = 0.75
TEAM_WITHIN_SHARE = 0.95
ALPHA_HELP = 0.01
ALPHA_HARM = 0.05  # the TOST's α for "not below SL's"
TEAM_MARGIN = 0.02  # the TOST's margin: a fraction of SL's mean team return over the pairs


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
    return f"p = {fmt_p(p)}"


def team_tost(group: UnitGroup, method: str) -> Tost | None:
    """T1's non-inferiority test: `method` against SL on team return over the class's pairs."""
    return group.tost(method, "sl", "team", TEAM_MARGIN)


def non_aligned_target(group: UnitGroup, method: str, team_p_lower: float | None = None) -> Target:
    """T1 for `method`; `team_p_lower` is the TOST's H0⁻ p after Holm's correction over the
    methods judged (`targets_of`); alone, the raw p is used."""
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
    tost = team_tost(group, method)
    if tost is not None:
        p_lower = tost.p_lower if team_p_lower is None else team_p_lower
        ok = p_lower < ALPHA_HARM
        shown = tost.describe(None if team_p_lower is None else team_p_lower)
        checks.append(
            Check(
                f"team return not below SL's (TOST, margin {TEAM_MARGIN:.0%} of SL's, "
                f"p⁻ < {ALPHA_HARM:g})",
                ok,
                f"{name} − SL per pair, {shown}: {'not worse' if ok else 'not shown'}",
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
    test = family_test(class_family(room), method, "sl", "team") if room is not None else None
    if test is None:
        checks.append(Check("team > SL where there is room to help", False, "no such pair ran"))
    else:
        p = test.p if test.p_holm is None else test.p_holm
        checks.append(
            Check(
                f"team > SL where there is room to help (Holm-adjusted p < {ALPHA_HELP:g})",
                test.diff.mean > 0 and p < ALPHA_HELP,
                f"{name} − SL = {test.diff} over {test.n_units} pairs, 95 % CI {test.ci}, "
                f"r = {test.effect:+.2f} ({_p(test.p)}, Holm {_p(p)}, higher in "
                f"{test.better:.0%})",
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
    team_p: dict[str, float] = {}  # T1's TOST p⁻ per method, Holm-adjusted over the methods
    if "non_aligned" in groups:
        tosts = {m: team_tost(groups["non_aligned"], m) for m in methods}
        raw = {m: t.p_lower for m, t in tosts.items() if t is not None}
        team_p = dict(zip(raw, holm(list(raw.values())), strict=True))
    for method in methods:
        if "non_aligned" in groups and method in groups["non_aligned"].rows:
            targets.append(non_aligned_target(groups["non_aligned"], method, team_p.get(method)))
        if "aligned" in groups and method in groups["aligned"].rows:
            targets.append(aligned_target(groups["aligned"], groups.get("room_to_help"), method))
        if "five_agents" in groups and method in groups["five_agents"].rows:
            targets.append(five_agent_target(groups["five_agents"], method))
    return targets
