"""The declared import order (the repository's ``.importlinter``, checked by ``make lint``):
docs/architecture.md draws exactly the floors it enforces, the tree keeps them, and a planted back
arrow fails the check (run on a copy of the package: the tree is not touched)."""

from __future__ import annotations

import configparser
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

import cobot_hmi

BACKEND = Path(__file__).resolve().parents[1]
DOC = BACKEND.parent / "docs" / "architecture.md"
PACKAGE = Path(cobot_hmi.__file__).parent
LINT_IMPORTS = Path(sys.executable).with_name("lint-imports")


CONFIG = BACKEND.parent / ".importlinter"


def _contracts() -> list[dict[str, Any]]:
    """The contracts as import-linter reads them: each option's lines a list."""
    parser = configparser.ConfigParser()
    parser.read(CONFIG, encoding="utf-8")
    contracts: list[dict[str, Any]] = []
    for section in parser.sections():
        if not section.startswith("importlinter:contract:"):
            continue
        options = parser[section]
        contract: dict[str, Any] = {
            key: [line.strip() for line in value.splitlines() if line.strip()]
            for key, value in options.items()
        }
        contract["type"] = options["type"]
        contract["exhaustive"] = options.getboolean("exhaustive")
        contracts.append(contract)
    return contracts


def _drawn_floors() -> list[list[str]]:
    """The ``text`` blocks of docs/architecture.md's "The import order, checked", in order."""
    text = DOC.read_text(encoding="utf-8")
    start = text.index("### The import order, checked")
    section = text[start : text.index("\n#", start + 1)]
    blocks = section.split("```text\n")[1:]
    return [
        [line.strip() for line in b.split("```")[0].splitlines() if line.strip()] for b in blocks
    ]


def test_the_architecture_doc_draws_the_floors_the_checker_enforces() -> None:
    contracts = _contracts()
    assert [c["type"] for c in contracts] == ["layers", "layers"]
    assert all(c.get("exhaustive") is True and not c.get("ignore_imports") for c in contracts)
    enforced = [
        [" : ".join(part.strip() for part in layer.split(":")) for layer in contract["layers"]]
        for contract in contracts
    ]
    assert enforced == _drawn_floors()


def _lint_imports(root: Path) -> subprocess.CompletedProcess[str]:
    """lint-imports with the project's contracts over the package found first under ``root``."""
    environ = {**os.environ, "PYTHONPATH": str(root)}
    return subprocess.run(
        [str(LINT_IMPORTS), "--no-cache", "--no-logo", "--config", str(CONFIG)],
        cwd=root,
        env=environ,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )


@pytest.fixture(scope="module")
def package_copy(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("import-order")
    shutil.copytree(
        PACKAGE, root / "cobot_hmi", ignore=shutil.ignore_patterns("*.so", "__pycache__")
    )
    return root


@pytest.mark.parametrize(
    ("importer", "planted", "refusal"),
    [
        # the robot building the API's status model again (robots under api)
        (
            "service/robots/robot.py",
            "from cobot_hmi.service.api import models",
            "cobot_hmi.service.robots is not allowed to import cobot_hmi.service.api",
        ),
        # the recorder reading the whole service's settings (recording under settings)
        (
            "service/recording/recorder.py",
            "from cobot_hmi.service.service_settings import ServiceSettings",
            "cobot_hmi.service.recording is not allowed to import "
            "cobot_hmi.service.service_settings",
        ),
        # the service knowing a door above it
        (
            "service/runtime.py",
            "import cobot_hmi.sparkplug.edge_node",
            "cobot_hmi.service is not allowed to import cobot_hmi.sparkplug",
        ),
    ],
)
def test_a_back_arrow_fails_the_check(
    package_copy: Path, importer: str, planted: str, refusal: str
) -> None:
    module = package_copy / "cobot_hmi" / importer
    kept = module.read_text(encoding="utf-8")
    assert _lint_imports(package_copy).returncode == 0  # the copy, as the tree, keeps the order
    module.write_text(kept + f"\n{planted}  # planted\n", encoding="utf-8")
    try:
        result = _lint_imports(package_copy)
    finally:
        module.write_text(kept, encoding="utf-8")
    assert result.returncode != 0
    # lint-imports wraps its lines at the terminal's width: compared with the spaces made one
    assert refusal in " ".join(result.stdout.split()), result.stdout


def test_a_package_without_a_floor_fails_the_check(package_copy: Path) -> None:
    new = package_copy / "cobot_hmi" / "service" / "newcomer"
    new.mkdir()
    (new / "__init__.py").write_text('"""Layer: service. Not yet given its floor."""\n')
    try:
        result = _lint_imports(package_copy)
    finally:
        shutil.rmtree(new)
    assert result.returncode != 0
    assert "cobot_hmi.service.newcomer" in result.stdout, result.stdout
