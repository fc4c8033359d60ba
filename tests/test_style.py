"""The code keeps the project's style: ``ruff check`` (pyflakes, pycodestyle, import order, bugbear, pyupgrade)
and ``ruff format --check`` pass on the whole tree with the settings in ``pyproject.toml``, and no function is
longer than ``LONGEST`` lines."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LONGEST = 80  # lines of a function, its decorators included


@pytest.mark.parametrize("command", [["check", "--output-format", "concise"], ["format", "--check"]])
def test_ruff_passes_on_the_whole_tree(command):
    run = subprocess.run([sys.executable, "-m", "ruff", *command, "."], cwd=ROOT, capture_output=True, text=True)
    assert run.returncode == 0, run.stdout + run.stderr


def test_no_function_is_longer_than_the_limit():
    long = [
        f"{path.relative_to(ROOT)}:{node.lineno} {node.name} ({length} lines)"
        for folder in ("furuta_drake", "benchmarks", "notebooks", "tests")
        for path in sorted((ROOT / folder).rglob("*.py"))
        for node in ast.walk(ast.parse(path.read_text()))
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
        for length in [node.end_lineno - node.lineno + 1 + len(node.decorator_list)]
        if length > LONGEST
    ]
    assert long == [], "\n".join(long)
