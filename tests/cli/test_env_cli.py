"""`coexist env check NAME` and `coexist env list`: a conforming env passes with one line per
check and exit 0; a broken one prints the failing check, naming the method, and exits 1; an
unknown name is a usage error naming the known ones."""

from __future__ import annotations

from dataclasses import replace

from typer.testing import CliRunner

from cli.main import app
from envs.registry import env_plugin, register_env

runner = CliRunner()


def test_a_conforming_env_passes(tinyline: str) -> None:
    answer = runner.invoke(app, ["env", "check", tinyline, "--episodes", "1"])
    assert answer.exit_code == 0, answer.output
    assert "ok   perspective:" in answer.output
    assert f"{tinyline}: all 9 checks passed" in answer.output
    listed = runner.invoke(app, ["env", "list"])
    assert listed.exit_code == 0 and tinyline in listed.output and "particle" in listed.output


def test_a_broken_env_fails_naming_the_method(tinyline: str) -> None:
    register_env(replace(env_plugin(tinyline), training="tinyline.nowhere:X"), replace=True)
    answer = runner.invoke(app, ["env", "check", tinyline, "--episodes", "1"])
    assert answer.exit_code == 1, answer.output
    assert "FAIL training: training: 'tinyline.nowhere:X' does not resolve" in answer.output
    assert "1 of 9 checks failed" in answer.output


def test_an_unknown_env_is_a_usage_error() -> None:
    answer = runner.invoke(app, ["env", "check", "nowhere"])
    assert answer.exit_code == 2
    assert "unknown environment 'nowhere'" in answer.output and "particle" in answer.output
