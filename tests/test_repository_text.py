"""What the repository's text may not say: tracker numbers, and the folders of the machine a
report was made on.

A reader of the repository has no access to the tracker, so a reference to one of its entries
by number says nothing; every tracked text file is checked. A report or a document is read on
other machines, so it names commands with paths relative to the repository or with variables
(`evaluation.command_line`), never a run's own folder such as one under the temporary directory
or a home directory.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
# A tracker reference: the word, then its number ("#" optional), any case, singular or plural.
TRACKER_NUMBER = re.compile(r"\bissues?\s+#?[0-9]", re.IGNORECASE)
# An absolute path into a machine's run, scratch or home folders; not a URL's path (a word
# character, a dot, `~` or `$` before the slash: `host:8000/tmp`, `./tmp/`, `~/tmp/`, `$X/tmp/`).
MACHINE_PATH = re.compile(r"(?<![\w.~$])/(?:tmp|work|home|root|Users|mnt|scratch|var/folders)/")
# Prose read on other machines: the reports and the documentation.
READ_ELSEWHERE = ("reports/", "docs/", "README.md", "CHANGELOG.md", "sdk/README.md", "docker/")


def _tracked_text() -> dict[str, str]:
    names = subprocess.run(
        ["git", "ls-files", "-z"], cwd=REPO, capture_output=True, check=True, text=True
    ).stdout.split("\0")
    texts = {}
    for name in filter(None, names):
        path = REPO / name
        if not path.is_file():  # deleted in the work tree, not yet committed
            continue
        data = path.read_bytes()
        if b"\0" in data[:8192]:
            continue
        try:
            texts[name] = data.decode("utf-8")
        except UnicodeDecodeError:
            continue
    return texts


def _hits(pattern: re.Pattern[str], texts: dict[str, str]) -> list[str]:
    return [
        f"{name}:{number}: {line.strip()[:120]}"
        for name, text in texts.items()
        for number, line in enumerate(text.splitlines(), start=1)
        if pattern.search(line)
    ]


def test_the_patterns_catch_what_they_are_for() -> None:
    n = 22  # spliced in, so that this file does not hold what it forbids
    tracker = [f"Issue {n} by kind", f"issues {n} and 18", f"(issue #{n})", f"ISSUES {n}"]
    assert all(TRACKER_NUMBER.search(s) for s in tracker)
    assert not any(TRACKER_NUMBER.search(s) for s in ["an issue with 3 parts", f"tissue {n}"])
    machine = ["sqlite:////tmp/zoo/models.db", "--run-dir /work/runs/x", "`/home/me/z`"]
    assert all(MACHINE_PATH.search(s) for s in machine)
    url = ["http://localhost:8000/tmp/x", "./tmp/x", "$ZOO/work/x", "~/tmp/x", "a/tmp/b"]
    assert not any(MACHINE_PATH.search(s) for s in url)


def test_no_tracker_numbers_in_the_repository() -> None:
    texts = _tracked_text()
    assert "README.md" in texts and len(texts) > 100  # the listing worked
    hits = _hits(TRACKER_NUMBER, texts)
    assert not hits, "say what the thing is, not its tracker number:\n" + "\n".join(hits)


def test_no_machine_paths_in_reports_or_docs() -> None:
    texts = {n: t for n, t in _tracked_text().items() if n.startswith(READ_ELSEWHERE)}
    assert any(n.startswith("reports/") for n in texts)
    hits = _hits(MACHINE_PATH, texts)
    assert not hits, "name paths relative to the repository or by a variable:\n" + "\n".join(hits)
