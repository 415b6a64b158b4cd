"""The corridor's registration: the entry point `tinyline` of the group `coexist.envs`."""

from envs.registry import EnvPlugin
from tinyline.drawing import CorridorDrawing
from tinyline.env import LINE, make_corridor

ENV = EnvPlugin(
    domain=LINE,
    make_env=make_corridor,
    training="tinyline.training:TRAINING",
    drawing=CorridorDrawing(),
)
