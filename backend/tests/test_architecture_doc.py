"""docs/architecture.md names what exists: every ``Class.method`` and ``module.function`` of its
frame's-way diagram is in the code, and every file path it cites is in the repository (a
renamed or removed part fails here, not in a reader's search)."""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import re
from pathlib import Path

import cobot_hmi

REPO = Path(__file__).resolve().parents[2]
DOC = REPO / "docs" / "architecture.md"
PACKAGE = Path(cobot_hmi.__file__).parent
PATH_BASES = (
    REPO,
    PACKAGE,
    PACKAGE / "service",
    REPO / "backend",
    REPO / "frontend" / "src",
    REPO / "frontend",
)


def _diagram() -> str:
    text = DOC.read_text(encoding="utf-8")
    start = text.index("## A frame's way")
    block = text.index("```", start)
    return text[block + 3 : text.index("```", block + 3)]


def _classes() -> dict[str, list[type]]:
    found: dict[str, list[type]] = {}
    for module_info in pkgutil.walk_packages([str(PACKAGE)], "cobot_hmi."):
        if module_info.name.endswith("__main__"):  # the command line, run on import
            continue
        module = importlib.import_module(module_info.name)
        for name, value in vars(module).items():
            if inspect.isclass(value) and value.__module__ == module.__name__:
                found.setdefault(name, []).append(value)
    return found


def test_every_name_of_the_frames_way_exists() -> None:
    classes = _classes()
    names = set(re.findall(r"\b([A-Za-z_][A-Za-z0-9_]*)\.([a-z_][a-z0-9_]*)\b", _diagram()))
    names = {(owner, attr) for owner, attr in names if attr not in ("py", "ts", "c")}
    assert names, "the diagram names no Class.method"
    missing = []
    for owner, attr in sorted(names):
        if owner[0].isupper():
            if not any(hasattr(c, attr) for c in classes.get(owner, [])):
                missing.append(f"{owner}.{attr}")
        elif not hasattr(importlib.import_module(f"cobot_hmi.{owner}"), attr):
            missing.append(f"{owner}.{attr}")
    assert not missing, f"docs/architecture.md names what the code does not have: {missing}"


def test_every_cited_file_exists() -> None:
    paths = set(re.findall(r"`([\w./-]+/[\w.-]+\.(?:py|c|h|ts|tsx|mjs|proto))`", DOC.read_text()))
    paths |= set(re.findall(r"\(([\w/]+/[\w.-]+\.(?:py|c|h|ts|tsx))[,:)]", _diagram()))
    missing = sorted(p for p in paths if not any((base / p).exists() for base in PATH_BASES))
    assert not missing, f"docs/architecture.md cites files that are not there: {missing}"
