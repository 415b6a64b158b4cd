"""Goal catalogue geometry: ids, order, target boxes and their mirrored influence boxes."""

import numpy as np
import pytest

from envs.particle.goals import GOAL_IDS, INFLUENCE_BOXES_G4, TARGET_BOXES_G4, goal_index


def box(goal: str) -> tuple[float, ...]:
    return tuple(TARGET_BOXES_G4[goal_index(goal)])


def influence(goal: str) -> tuple[float, ...]:
    return tuple(INFLUENCE_BOXES_G4[goal_index(goal)])


def test_ids_and_order() -> None:
    assert len(GOAL_IDS) == len(set(GOAL_IDS)) == 35
    assert GOAL_IDS[:6] == ("a0", "a1", "a2", "a3", "a4", "b0")
    assert GOAL_IDS[24] == "e4"
    assert GOAL_IDS[25:30] == ("a", "b", "c", "d", "e")
    assert GOAL_IDS[30:] == ("0", "1", "2", "3", "4")
    assert [goal_index(g) for g in GOAL_IDS] == list(range(35))


@pytest.mark.parametrize(
    ("goal", "expected"),
    [
        ("a0", (0.0, 0.2, 0.0, 0.2)),
        ("b3", (0.2, 0.4, 0.6, 0.8)),
        ("e4", (0.8, 1.0, 0.8, 1.0)),
        ("c", (0.4, 0.6, 0.0, 1.0)),
        ("0", (0.0, 1.0, 0.0, 0.2)),
        ("4", (0.0, 1.0, 0.8, 1.0)),
    ],
)
def test_target_boxes(goal: str, expected: tuple[float, ...]) -> None:
    assert box(goal) == pytest.approx(expected)


@pytest.mark.parametrize(
    ("goal", "mirror"),
    [("c4", "c0"), ("b3", "d1"), ("a", "e"), ("c", "c"), ("1", "3"), ("e0", "a4")],
)
def test_influence_is_the_mirrored_goal(goal: str, mirror: str) -> None:
    assert influence(goal) == box(mirror)


def test_every_influence_box_mirrors_its_target_box() -> None:
    x_lo, x_hi, y_lo, y_hi = TARGET_BOXES_G4.T
    mirrored = np.stack([1 - x_hi, 1 - x_lo, 1 - y_hi, 1 - y_lo], axis=1)
    np.testing.assert_allclose(INFLUENCE_BOXES_G4, mirrored, atol=1e-12)
    # the mirror of a goal is itself a goal, and mirroring twice gives the goal back
    targets = [tuple(b) for b in TARGET_BOXES_G4]
    for g in range(35):
        m = targets.index(tuple(INFLUENCE_BOXES_G4[g]))
        assert tuple(INFLUENCE_BOXES_G4[m]) == targets[g]


def test_boxes_are_inside_the_unit_square_with_area_of_cell_row_or_column() -> None:
    widths = TARGET_BOXES_G4[:, 1] - TARGET_BOXES_G4[:, 0]
    heights = TARGET_BOXES_G4[:, 3] - TARGET_BOXES_G4[:, 2]
    areas = widths * heights
    np.testing.assert_allclose(areas[:25], 0.04)
    np.testing.assert_allclose(areas[25:], 0.2)
    assert TARGET_BOXES_G4.min() == 0.0 and TARGET_BOXES_G4.max() == 1.0


@pytest.mark.parametrize("bad", ["f0", "a5", "", "A0", "aa"])
def test_unknown_goal_is_named(bad: str) -> None:
    with pytest.raises(ValueError, match=repr(bad)):
        goal_index(bad)
