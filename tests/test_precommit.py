"""The pre-commit hooks (.pre-commit-config.yaml) run the very checks of .ci/run: its ruff and mypy stages'
commands, each whole (no file list appended), with the installed tools (`language: system`: offline)."""

from __future__ import annotations

import re
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
#: the stages of .ci/run that check the code without running it (`echo "== NAME"; COMMAND && COMMAND`)
CHECK_STAGES = ("ruff", "mypy")


def ci_check_commands(text: str) -> list[str]:
    """The commands of .ci/run's check stages, in order."""
    commands = []
    for m in re.finditer(r'^echo "== (\w+)"; (.+)$', text, flags=re.M):
        if m.group(1) in CHECK_STAGES:
            commands += [c.strip() for c in m.group(2).split("&&")]
    return commands


def test_the_hooks_run_the_commands_of_ci_run():
    ci = ci_check_commands((ROOT / ".ci" / "run").read_text())
    assert ci == ["ruff check .", "ruff format --check .", "mypy"]  # .ci/run's stages were found
    config = yaml.safe_load((ROOT / ".pre-commit-config.yaml").read_text())
    hooks = [h for repo in config["repos"] for h in repo["hooks"]]
    assert all(repo["repo"] == "local" for repo in config["repos"])  # nothing to download
    assert [h["entry"] for h in hooks] == ci
    for h in hooks:
        assert h["language"] == "system" and h["pass_filenames"] is False, h["id"]


def test_the_parser_reads_a_stage_with_several_commands():
    text = 'echo "== numba"; python -m x\necho "== ruff"; ruff a && ruff b\necho "== tests"; pytest\n'
    assert ci_check_commands(text) == ["ruff a", "ruff b"]
