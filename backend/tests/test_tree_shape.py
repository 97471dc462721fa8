"""The shape of the tree: no function over 80 lines, no class over 25 methods, in the package and
the benches (docs/architecture.md, "Layers and the module map"). What the line count of a file
once stood for: a function a reader can hold at once, a class with one job. Each finding is
listed with its place, so a failure says what to split."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

MAX_FUNCTION_LINES = 80
MAX_CLASS_METHODS = 25
BACKEND = Path(__file__).resolve().parents[1]
TREES = (BACKEND / "src" / "cobot_hmi", BACKEND.parent / "bench")


def _sources() -> list[Path]:
    return sorted(
        path
        for tree in TREES
        for path in tree.rglob("*.py")
        if "generated" not in path.parts and "__pycache__" not in path.parts
    )


def findings(source: str, name: str) -> list[str]:
    """Every function longer than ``MAX_FUNCTION_LINES`` and class with more methods than
    ``MAX_CLASS_METHODS`` in ``source`` (a module's text), as ``name:line what``."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            lines = (node.end_lineno or node.lineno) - node.lineno + 1
            if lines > MAX_FUNCTION_LINES:
                out.append(f"{name}:{node.lineno} {node.name}() is {lines} lines")
        elif isinstance(node, ast.ClassDef):
            methods = sum(isinstance(b, ast.FunctionDef | ast.AsyncFunctionDef) for b in node.body)
            if methods > MAX_CLASS_METHODS:
                out.append(f"{name}:{node.lineno} class {node.name} has {methods} methods")
    return out


def test_no_function_over_80_lines_and_no_class_over_25_methods() -> None:
    found = [
        finding
        for path in _sources()
        for finding in findings(
            path.read_text(encoding="utf-8"), str(path.relative_to(BACKEND.parent))
        )
    ]
    assert not found, "split by responsibility:\n" + "\n".join(found)


def test_the_check_finds_a_long_function_and_a_wide_class() -> None:
    """The check itself, on a planted violation of each kind (and on their allowed sizes)."""
    long_body = "\n".join(f"    x{i} = {i}" for i in range(MAX_FUNCTION_LINES))
    wide = "\n".join(f"    def m{i}(self): ..." for i in range(MAX_CLASS_METHODS + 1))
    planted = f"def long():\n{long_body}\n\n\nclass Wide:\n{wide}\n"
    assert findings(planted, "planted.py") == [
        f"planted.py:1 long() is {MAX_FUNCTION_LINES + 1} lines",
        f"planted.py:{MAX_FUNCTION_LINES + 4} class Wide has {MAX_CLASS_METHODS + 1} methods",
    ]
    fitting_body = "\n".join(f"    x{i} = {i}" for i in range(MAX_FUNCTION_LINES - 1))
    fitting = "\n".join(f"    def m{i}(self): ..." for i in range(MAX_CLASS_METHODS))
    assert findings(f"def f():\n{fitting_body}\n\n\nclass C:\n{fitting}\n", "ok.py") == []


@pytest.mark.parametrize("tree", TREES, ids=lambda p: p.name)
def test_the_trees_are_there(tree: Path) -> None:
    assert any(tree.rglob("*.py")), f"{tree}: no Python sources (the check would pass on nothing)"
