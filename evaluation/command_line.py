"""The command line a report prints: every setting spelled out, no path of the machine it ran on.

A report is read on other machines, so the command it names must not carry the run's own
folders (`/tmp/...`, a home directory) or a database password. `portable_command` rewrites the
words of a command before they are joined:

- a path inside the repository becomes relative to the repository's root;
- the folder of the zoo's SQLite store (`--store-url sqlite:////abs/dir/models.db`) becomes
  `$ZOO`, in the store URL and in every path under it (`--run-dir`);
- any other store URL (PostgreSQL: it may hold a password) becomes `$COEXIST_STORE_URL`;
- any other absolute path becomes `$SCRATCH/<its last part>`.

`VARIABLES` says what each variable stands for; a report that prints a command prints
`variables_note(command)` beside it. `portable_path` does the same for a lone path.
"""

from __future__ import annotations

import re
import shlex
from collections.abc import Sequence
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
SQLITE_ABSOLUTE = "sqlite:////"
VARIABLES = {
    "$ZOO": "the folder of the zoo's SQLite store (`make serve`'s is `.coexist`)",
    "$COEXIST_STORE_URL": "the zoo's store URL",
    "$SCRATCH": "a scratch folder of the run",
}
# Characters that keep a double-quoted word's `$VAR` expanding and need no escape inside it.
_DOUBLE_QUOTE_SAFE = re.compile(r'^[^"\\`!]*$')


def portable_command(words: Sequence[str], root: Path = REPO_ROOT) -> str:
    """Join `words` as a shell command with the machine's own paths replaced (module docstring).

    `words` are the command's words before quoting; the answer is one line that a POSIX shell
    reads back as the same words once `$ZOO` (and the others used) are set.
    """
    zoo = _zoo_folder(words)
    out: list[str] = []
    for i, word in enumerate(words):
        after_store_flag = i > 0 and words[i - 1] == "--store-url"
        if after_store_flag or word.startswith("sqlite:") or "://" in word:
            out.append(_store_url(word, zoo, root))
        else:
            out.append(_path(word, zoo, root))
    return " ".join(_quote(word) for word in out)


def portable_path(path: Path | str, root: Path = REPO_ROOT) -> str:
    """`path` as a report may print it: relative to the repository, or under `$SCRATCH`."""
    return _path(str(path), None, root)


def variables_note(command: str) -> str:
    """One sentence naming what each variable in `command` stands for ('' when it has none)."""
    used = [f"`{name}` is {meaning}" for name, meaning in VARIABLES.items() if name in command]
    return "; ".join(used) + "." if used else ""


def _zoo_folder(words: Sequence[str]) -> Path | None:
    for i, word in enumerate(words[:-1]):
        if word == "--store-url" and words[i + 1].startswith(SQLITE_ABSOLUTE):
            return Path(words[i + 1][len("sqlite:///") :]).parent
    return None


def _store_url(url: str, zoo: Path | None, root: Path) -> str:
    if not url.startswith("sqlite:"):
        return "$COEXIST_STORE_URL"
    if url.startswith(SQLITE_ABSOLUTE):
        return "sqlite:///" + _path(url[len("sqlite:///") :], zoo, root)
    return url


def _path(word: str, zoo: Path | None, root: Path) -> str:
    if not word.startswith("/"):
        return word
    path = Path(word)
    if path.is_relative_to(root):
        return path.relative_to(root).as_posix() or "."
    if zoo is not None and path.is_relative_to(zoo):
        rest = path.relative_to(zoo).as_posix()
        return "$ZOO" if rest == "." else f"$ZOO/{rest}"
    return f"$SCRATCH/{path.name}"


def _quote(word: str) -> str:
    # A word this module made starts with its one variable; double quotes let the shell expand
    # it. Anything else (or a word with a second `$`) is quoted literally.
    made = word.startswith(("$", "sqlite:///$")) and word.count("$") == 1
    if made and _DOUBLE_QUOTE_SAFE.match(word):
        return f'"{word}"'
    return shlex.quote(word)
