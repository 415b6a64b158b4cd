"""The registration: the entry point `mpe2_landmarks` of the group `coexist.envs`."""

from envs.registry import EnvPlugin
from mpe2_landmarks.drawing import LandmarksDrawing
from mpe2_landmarks.env import LANDMARKS_DOMAIN, make_landmarks_env

ENV = EnvPlugin(
    domain=LANDMARKS_DOMAIN,
    make_env=make_landmarks_env,
    training="mpe2_landmarks.training:TRAINING",
    drawing=LandmarksDrawing(),
)
