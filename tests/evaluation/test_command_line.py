"""`evaluation.command_line`: a report's command without the machine's folders, and a shell that
reads it back, with the variables set, as the words that ran."""

from __future__ import annotations

import subprocess
from pathlib import Path

from evaluation.command_line import (
    REPO_ROOT,
    portable_command,
    portable_path,
    variables_note,
)


def _shell_words(command: str, env: dict[str, str]) -> list[str]:
    """The words a POSIX shell makes of `command`, one per line (`printf`)."""
    script = "printf '%s\\n' " + command.split(" ", 1)[1]
    out = subprocess.run(["sh", "-c", script], env=env, capture_output=True, text=True, check=True)
    return out.stdout.splitlines()


def test_the_zoo_folder_becomes_a_variable_and_reads_back() -> None:
    zoo = "/tmp/runs/fr 1/.coexist"  # a space too: the quoting must keep the word whole
    words = [
        "coexist",
        "eval",
        "--store-url",
        f"sqlite:///{zoo}/models.db",
        "--run-dir",
        f"{zoo}/runs/bootstrap",
        "--out",
        str(REPO_ROOT / "reports" / "paper"),
        "--seed",
        "7",
    ]
    command = portable_command(words)
    assert "/tmp/" not in command and str(REPO_ROOT) not in command
    assert '"sqlite:///$ZOO/models.db"' in command and '"$ZOO/runs/bootstrap"' in command
    assert "--out reports/paper" in command
    back = _shell_words(command, {"ZOO": zoo})
    assert back == [*words[1:7], "reports/paper", *words[8:]]
    assert "`$ZOO` is the folder" in variables_note(command)


def test_a_server_store_url_is_never_printed() -> None:
    url = "postgresql+psycopg://coexist:s3cret@db.internal:5432/coexist"
    command = portable_command(["coexist", "eval", "--store-url", url])
    assert "s3cret" not in command and "db.internal" not in command
    assert command.endswith('"$COEXIST_STORE_URL"')
    assert "`$COEXIST_STORE_URL` is the zoo's store URL" in variables_note(command)


def test_other_absolute_paths_and_relative_ones() -> None:
    command = portable_command(["x", "--timing-log", "/home/me/log.jsonl", "--out", "reports/p"])
    assert command == 'x --timing-log "$SCRATCH/log.jsonl" --out reports/p'
    assert portable_command(["x", "--store-url", "sqlite:///.coexist/models.db"]) == (
        "x --store-url sqlite:///.coexist/models.db"
    )
    assert portable_path(REPO_ROOT / "reports" / "cooking") == "reports/cooking"
    assert portable_path(Path("/var/tmp/out")) == "$SCRATCH/out"
    assert variables_note("coexist eval --seed 1") == ""


def test_a_word_with_its_own_dollar_stays_literal() -> None:
    command = portable_command(["x", "--run-dir", "/home/me/a$b"])
    assert command == "x --run-dir '$SCRATCH/a$b'"
