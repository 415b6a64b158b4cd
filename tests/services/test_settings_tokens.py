"""Outside development mode the server refuses tokens that are easy to guess: the admin token
(and the read token, when set) needs 16+ characters, 8+ different ones, no whitespace; in
development mode anything but an empty admin token goes. `coexist serve` says so and exits 2."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from pydantic import SecretStr

from services.settings import InsecureSettings, Settings

STRONG = "b6f1c0e7a93d4e21"
WEAK = {
    "a space": " ",
    "one character": "a",
    "the default with a space": "dev-token ",
    "short": "short-token",
    "inner whitespace": "0123456789 abcdefgh",
    "a trailing newline": "0123456789abcdefgh\n",
    "one character repeated": "a" * 32,
    "four characters repeated": "0123" * 8,
}


@pytest.mark.parametrize("token", list(WEAK.values()), ids=list(WEAK))
def test_weak_tokens_are_refused_outside_dev_mode(token: str) -> None:
    with pytest.raises(InsecureSettings, match="COEXIST_ADMIN_TOKEN"):
        Settings(admin_token=SecretStr(token)).check_secure()
    read = Settings(admin_token=SecretStr(STRONG), read_token=SecretStr(token))
    with pytest.raises(InsecureSettings, match="COEXIST_READ_TOKEN"):
        read.check_secure()


def test_strong_tokens_pass_and_dev_mode_allows_weak_ones() -> None:
    Settings(admin_token=SecretStr(STRONG), read_token=SecretStr(STRONG[::-1])).check_secure()
    Settings(admin_token=SecretStr("a"), read_token=SecretStr("b"), dev_mode=True).check_secure()
    with pytest.raises(InsecureSettings, match="empty"):
        Settings(admin_token=SecretStr(" "), dev_mode=True).check_secure()


def test_serve_refuses_a_weak_token(tmp_path: Path) -> None:
    env = {k: v for k, v in os.environ.items() if not k.startswith("COEXIST_")}
    env.update(COEXIST_DATA_DIR=str(tmp_path), COEXIST_ADMIN_TOKEN="dev-token ")
    result = subprocess.run(
        [sys.executable, "-m", "cli.main", "serve", "--no-bootstrap"],
        env=env,
        capture_output=True,
        timeout=120,
    )
    assert result.returncode == 2, result.stderr.decode()[-2000:]
    assert b"COEXIST_ADMIN_TOKEN has 10 characters, fewer than 16" in result.stderr
