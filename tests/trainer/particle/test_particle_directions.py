"""The impact direction gate (`trainer.particle.directions`) on hand-built networks.

The partner's task network is built so that its value is minus ten times the ego's L1 distance to
the centre of the partner's influence area; the impact networks are linear in the ego's position:
each push's Q is how far it points towards that centre. The "dead" variant never prefers one of
the pushes it needs, as the first zoo's `c2` never pushed left.
"""

from __future__ import annotations

import json
from dataclasses import asdict, replace

import numpy as np
import pytest
import torch

from envs.particle.goals import INFLUENCE_BOXES_G4, goal_index
from policy.qnet import QNetSpec, StackedQNet
from trainer.config import ImpactConfig
from trainer.particle.directions import dead_pushes, direction_checks
from trainer.particle.gates import impact_gates

SPEC = QNetSpec(obs_dim=8, n_actions=5, hidden=(4, 4))
CONFIG = replace(ImpactConfig(), direction_states=4096, eval_episodes=4, eval_steps=30)
# Q-vector direction of each action (rest, up, down, left, right) in (x, y)
DIRECTIONS = np.array([[0, 0], [0, 1], [0, -1], [-1, 0], [1, 0]], dtype=np.float32)


def _centre(goal: str) -> np.ndarray:
    box = INFLUENCE_BOXES_G4[goal_index(goal)]
    return np.array([(box[0] + box[1]) / 2, (box[2] + box[3]) / 2], dtype=np.float32)


def _stack(layers: list[tuple[np.ndarray, np.ndarray]]) -> StackedQNet:
    net = StackedQNet(SPEC, 1)
    with torch.no_grad():
        for k, (w, b) in enumerate(layers):
            net.weights[k].copy_(torch.from_numpy(w[None].astype(np.float32)))
            net.biases[k].copy_(torch.from_numpy(b[None].astype(np.float32)))
    return net


def partner_task_net(goal: str) -> StackedQNet:
    """Q(a) = -10 (|x_e - c_x| + |y_e - c_y|) for every action, on the view (partner, ego)."""
    cx, cy = _centre(goal)
    w1, b1 = np.zeros((4, 8)), np.array([-cx, cx, -cy, cy])
    w1[0, 4], w1[1, 4], w1[2, 5], w1[3, 5] = 1, -1, 1, -1  # ReLU(±(x - c)): |x - c| in two parts
    w2, b2 = np.eye(4), np.zeros(4)
    w3, b3 = np.full((5, 4), -10.0), np.zeros(5)
    return _stack([(w1, b1), (w2, b2), (w3, b3)])


def impact_net(goal: str, dead: int | None = None) -> StackedQNet:
    """Q(a) = d_a · (c - ego) on the view (ego, partner); action `dead` gets -10 everywhere."""
    c = _centre(goal)
    w1, b1 = np.zeros((4, 8)), np.zeros(4)
    w1[0, 0], w1[1, 1] = 1, 1  # x, y of the ego (in [0, 1]: ReLU keeps them)
    w2, b2 = np.eye(4), np.zeros(4)
    w3 = np.zeros((5, 4))
    w3[:, :2] = -DIRECTIONS  # -d_a · ego
    b3 = DIRECTIONS @ c  # + d_a · c
    if dead is not None:
        w3[dead], b3[dead] = 0, -10.0
    return _stack([(w1, b1), (w2, b2), (w3, b3)])


def test_a_network_that_points_towards_the_area_passes() -> None:
    [check] = direction_checks(impact_net("c2"), partner_task_net("c2"), CONFIG, seed=1)
    assert check.passed, check
    assert check.toward_share > 0.99
    assert all(r is not None and r > 0.95 for r in check.push_recall.values())


@pytest.mark.parametrize(("dead", "name"), [(3, "left"), (2, "down")])
def test_a_dead_needed_push_fails(dead: int, name: str) -> None:
    [check] = direction_checks(impact_net("c2", dead=dead), partner_task_net("c2"), CONFIG, 1)
    assert not check.passed
    assert check.push_recall[name] == 0.0
    assert dead_pushes(check, CONFIG) == [name]


def test_a_push_no_state_needs_is_not_judged() -> None:
    """`a0`'s influence area is the top-right cell: no state clearly needs left or down."""
    [check] = direction_checks(impact_net("a0", dead=3), partner_task_net("a0"), CONFIG, 1)
    assert check.push_recall["left"] is None and check.passed


def test_the_impact_gate_includes_the_directions_and_records_them() -> None:
    goal = goal_index("c2")
    partner = partner_task_net("c2")
    [good] = impact_gates(impact_net("c2"), partner, [goal], CONFIG, seed=3)
    [dead] = impact_gates(impact_net("c2", dead=3), partner, [goal], CONFIG, seed=3)
    assert good.passed and good.dead_pushes == ()
    assert not dead.passed and dead.dead_pushes == ("left",)
    # the figures go into the lineage as JSON
    assert json.loads(json.dumps(dead.metrics()))["push_recall"]["left"] == 0.0
    assert set(asdict(dead)) >= {"toward_share", "push_recall", "dead_pushes"}


def test_stacks_of_different_sizes_are_refused() -> None:
    two = StackedQNet(SPEC, 2)
    with pytest.raises(ValueError, match="partner_task_nets: expected one member per impact"):
        direction_checks(two, partner_task_net("c2"), CONFIG, seed=0)
