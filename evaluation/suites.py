"""The evaluation suites by name: what `coexist eval --suite NAME` runs.

| name        | suite                                           | reproduces               |
|-------------|-------------------------------------------------|--------------------------|
| `paper`     | `evaluation.paper.command.PAPER_SUITE`          | the particle world, §4.2 |
| `inference` | `evaluation.inference.command.INFERENCE_SUITE`  | online goal inference    |
| `cooking`   | `evaluation.cooking.command.COOKING_SUITE`      | the kitchen, Fig. 9      |
| `partners`  | `evaluation.partners.command.PARTNERS_SUITE`    | every method against     |
|             |                                                 | partners not coexist's   |

To add a suite, add its folder `evaluation/<suite>/` whose `command.py` implements
`evaluation.base.Suite`, and one entry to `SUITES`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from evaluation.base import Suite
from evaluation.cooking.command import COOKING_SUITE
from evaluation.inference.command import INFERENCE_SUITE
from evaluation.paper.command import PAPER_SUITE
from evaluation.partners.command import PARTNERS_SUITE

SUITES: dict[str, Suite[Any]] = {
    suite.name: suite for suite in (PAPER_SUITE, INFERENCE_SUITE, COOKING_SUITE, PARTNERS_SUITE)
}
DEFAULT_SUITE = PAPER_SUITE.name  # `coexist eval` without --suite


def get_suite(name: str) -> Suite[Any]:
    """The suite called `name`; ValueError naming the known ones for any other name."""
    try:
        return SUITES[name]
    except KeyError:
        raise ValueError(f"unknown suite {name!r}; expected {_listed(repr)}") from None


def suites_help() -> str:
    """`--suite`'s help: every suite's name and what it reproduces."""
    return _listed(lambda name: f"{name!r} {SUITES[name].help}") + "."


def _listed(word: Callable[[str], str]) -> str:
    """'a', 'b' or 'c'."""
    words = [word(name) for name in SUITES]
    return ", ".join(words[:-1]) + " or " + words[-1] if len(words) > 1 else words[0]
