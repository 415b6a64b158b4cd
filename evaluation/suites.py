"""The evaluation suites by name: what `coexist eval --suite NAME` runs.

| name        | suite                                           | reproduces               |
|-------------|-------------------------------------------------|--------------------------|
| `paper`     | `evaluation.paper.command.PAPER_SUITE`          | the particle world, §4.2 |
| `inference` | `evaluation.inference.command.INFERENCE_SUITE`  | online goal inference    |
| `cooking`   | `evaluation.cooking.command.COOKING_SUITE`      | the kitchen, Fig. 9      |
| `partners`  | `evaluation.partners.command.PARTNERS_SUITE`    | every method against     |
|             |                                                 | partners not coexist's   |
| `pairs`     | `evaluation.pairs.command.PAIRS_SUITE`          | every method on goal     |
|             |                                                 | pairs of any `--env`     |

Suites are plugins like environments (`envs.registry`): each is an entry point of the group
`coexist.suites` naming an object that implements `evaluation.base.Suite`, loaded once per
process. coexist's own are declared in this project's `pyproject.toml`; a package that brings
an environment can bring its experiments the same way (`docs/extending.md`).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from functools import cache
from importlib.metadata import entry_points
from typing import Any

from evaluation.base import Suite

log = logging.getLogger(__name__)

ENTRY_POINT_GROUP = "coexist.suites"
DEFAULT_SUITE = "paper"  # `coexist eval` without --suite


@cache
def suites() -> dict[str, Suite[Any]]:
    """Every suite of the `coexist.suites` entry points, by name (`paper` first, then the others
    by name); one that fails to load is logged and left out."""
    found: dict[str, Suite[Any]] = {}
    for point in sorted(entry_points(group=ENTRY_POINT_GROUP), key=lambda p: p.name):
        try:
            suite = point.load()
        except Exception as exc:  # a broken plugin must not take `coexist eval` down
            log.warning("suite plugin %s (%s) failed to load: %s", point.name, point.value, exc)
            continue
        if getattr(suite, "name", None) != point.name:
            log.warning("suite plugin %s (%s): its name differs", point.name, point.value)
            continue
        found.setdefault(point.name, suite)
    first = {name: found[name] for name in (DEFAULT_SUITE,) if name in found}
    return {**first, **found}


def get_suite(name: str) -> Suite[Any]:
    """The suite called `name`; ValueError naming the known ones for any other name."""
    try:
        return suites()[name]
    except KeyError:
        raise ValueError(f"unknown suite {name!r}; expected {_listed(repr)}") from None


def suites_help() -> str:
    """`--suite`'s help: every suite's name and what it reproduces."""
    return _listed(lambda name: f"{name!r} {suites()[name].help}") + "."


def _listed(word: Callable[[str], str]) -> str:
    """'a', 'b' or 'c'."""
    words = [word(name) for name in suites()]
    if not words:
        return "a suite, but none is installed (reinstall coexist: `make setup`)"
    return ", ".join(words[:-1]) + " or " + words[-1] if len(words) > 1 else words[0]
