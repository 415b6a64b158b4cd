"""What a training job trains, validated the way `coexist train` validates it.

| kind     | uses            | rules                                                         |
|----------|-----------------|---------------------------------------------------------------|
| `task`   | env, goals      | goals: 'all' or comma-separated goal ids of `env`             |
| `impact` | env, goals      | the same                                                      |
| `joint`  | env, combos     | particle world only; combos 'a2+b3,c+c4', 2..5 goals each     |
| `zoo`    | env, goals, combos (optional) | tasks, impacts, then JL combinations            |

Every kind also takes `seed` (0..`MAX_SEED`) and `steps` (1..`MAX_STEPS` batched environment
steps per batch of goals; None: the config's default, 12 000 for task networks). The bounds keep
every seed a valid seed of each RNG the trainer feeds (32-bit ones included) and a job's length
finite; `goals` and `combos` are at most `MAX_TEXT` characters. Errors are `InvalidArgument`
naming the field, which the API answers with 422.
"""

from __future__ import annotations

import sys
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from model_store.errors import InvalidArgument, brief

JOB_KINDS = ("task", "impact", "joint", "zoo")
MAX_SEED = 2**31 - 1
MAX_STEPS = 1_000_000  # ~83 times the default of a task network
MAX_TEXT = 4096  # characters of `goals` or `combos`


@dataclass(frozen=True)
class JobSpec:
    kind: str
    env: str = "particle"
    goals: str = "all"
    combos: str = ""
    seed: int = 0
    steps: int | None = None

    def validate(self) -> JobSpec:
        """Check every field (see the module docstring); return self."""
        from envs.base import check_goal
        from envs.registry import get_domain
        from trainer.plugins import env_trainer

        if self.kind not in JOB_KINDS:
            raise InvalidArgument(
                f"kind: expected one of {JOB_KINDS}, got {brief(self.kind)}", field="kind"
            )
        try:
            domain = get_domain(self.env)
        except ValueError as err:
            raise InvalidArgument(f"env: {err}", field="env") from None
        if not isinstance(self.seed, int) or not 0 <= self.seed <= MAX_SEED:
            raise InvalidArgument(
                f"seed: expected an integer in 0..{MAX_SEED}, got {brief(self.seed)}", field="seed"
            )
        if self.steps is not None and (
            not isinstance(self.steps, int) or not 1 <= self.steps <= MAX_STEPS
        ):
            raise InvalidArgument(
                f"steps: expected an integer in 1..{MAX_STEPS}, got {brief(self.steps)}",
                field="steps",
            )
        for field in ("goals", "combos"):
            if len(getattr(self, field)) > MAX_TEXT:
                raise InvalidArgument(f"{field}: at most {MAX_TEXT} characters", field=field)
        if self.goals != "all":
            chosen = [g.strip() for g in self.goals.split(",") if g.strip()]
            if not chosen:
                raise InvalidArgument("goals: expected 'all' or goal ids", field="goals")
            for goal in chosen:
                _check(check_goal, domain, goal, "goals")
        if self.combos and self.kind in ("task", "impact"):
            raise InvalidArgument(f"combos: a {self.kind} job takes no combos", field="combos")
        if self.kind == "joint" and not self.combos:
            raise InvalidArgument("combos: a joint job needs at least one", field="combos")
        if self.combos:
            no_joint = env_trainer(self.env).no_joint_reason
            if no_joint:
                raise InvalidArgument(f"combos: {no_joint}", field="combos")
            for combo in (c for c in self.combos.split(",") if c.strip()):
                goals = [g.strip() for g in combo.split("+")]
                if not 2 <= len(goals) <= 5:
                    raise InvalidArgument(f"combos: {combo}: expected 2 to 5 goals", field="combos")
                for goal in goals:
                    _check(check_goal, domain, goal, "combos")
        return self

    def to_json(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> JobSpec:
        return cls(**data)


def _check(check_goal: Any, domain: Any, goal: str, field: str) -> None:
    try:
        check_goal(domain, goal, field)
    except ValueError as err:
        raise InvalidArgument(str(err), field=field) from None


# `coexist train`'s exit status when every batch trained and registered but a network's final
# gate failed (after the retries): the job table records it as `gate_failed`, not `succeeded`
GATE_FAILED_EXIT_CODE = 4


def train_command(spec: JobSpec, run_dir: Path) -> list[str]:
    """`python -m cli.main train <kind> ... --resume`: always resumable from `run_dir`. No
    store URL: a command line is public (`ps`, the job's log), and the store needs the
    database's password, so the runner hands both over in the environment, apart
    (`COEXIST_STORE_URL`, `PGPASSWORD`: `trainer.jobs.runner`)."""
    cmd = [sys.executable, "-m", "cli.main", "train", spec.kind, "--env", spec.env]
    if spec.kind != "joint":
        cmd += ["--goals", spec.goals]
    if spec.combos:
        cmd += ["--combos", spec.combos]
    cmd += ["--seed", str(spec.seed)]
    if spec.steps is not None:
        cmd += ["--steps", str(spec.steps)]
    return [*cmd, "--run-dir", str(run_dir), "--resume"]
