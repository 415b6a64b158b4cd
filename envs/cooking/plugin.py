"""The kitchen's registration (`envs.registry.EnvPlugin`), the entry point `cooking` of the group
`coexist.envs` in this project's `pyproject.toml`.

No state adapter: a kitchen's state is not one row per agent (objects, plates, who holds what,
the layout), so cooking clients send observations (`envs.cooking.observation`)."""

from envs.cooking.domain import COOKING
from envs.cooking.env import make_cooking_env
from envs.registry import EnvPlugin

ENV = EnvPlugin(
    domain=COOKING,
    make_env=make_cooking_env,
    training="trainer.cooking:TRAINER",
    drawing=COOKING,
)
