"""docker-compose.yml: the product as two hosts, checked without a Docker engine.

``docker compose config`` (or Debian's standalone ``docker-compose``) parses, validates and
renders the file; these tests read what it rendered: the two services built from the repo's
Dockerfiles, their own network with the emulator at a fixed address the backend points at,
the panel published on port 8000, health checks, and settings that are real ``COBOT_HMI_*``
names. The Dockerfiles' ``COPY`` sources are checked against the repository too. Only a
machine without the docker client skips (no engine is needed: ``config`` only parses).
"""

from __future__ import annotations

import glob
import ipaddress
import os
import shlex
import shutil
import subprocess
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import pytest
import yaml

from cobot_hmi.cli import build_parser
from cobot_hmi.service.settings import ServiceSettings, env_name

ROOT = Path(__file__).resolve().parents[2]
COMPOSE_FILE = ROOT / "docker-compose.yml"
DOCKER = shutil.which("docker")

pytestmark = pytest.mark.skipif(
    DOCKER is None,
    reason="no docker client on this machine: docker-compose.yml is not checked here",
)


def _compose_command() -> list[str]:
    """``docker compose`` (the plugin) if present, else the standalone ``docker-compose``."""
    assert DOCKER is not None
    plugin = subprocess.run(
        [DOCKER, "compose", "version"], capture_output=True, timeout=30, check=False
    )
    if plugin.returncode == 0:
        return [DOCKER, "compose"]
    standalone = shutil.which("docker-compose")
    if standalone is not None:
        return [standalone]
    pytest.fail(
        "the docker client is here but has no compose command (neither `docker compose` nor "
        "`docker-compose`): `make system-deps` installs Debian's docker-compose"
    )


def _render(extra_env: Mapping[str, str] | None = None) -> dict[str, Any]:
    # The file's own defaults, whatever this shell exports; plus what a test asks for.
    env = {k: v for k, v in os.environ.items() if not k.startswith("COBOT_HMI_")}
    env.update(extra_env or {})
    result = subprocess.run(
        [*_compose_command(), "-f", str(COMPOSE_FILE), "config"],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert result.returncode == 0, f"compose config failed:\n{result.stderr}"
    rendered = yaml.safe_load(result.stdout)
    assert isinstance(rendered, dict)
    return rendered


@pytest.fixture(scope="module")
def config() -> dict[str, Any]:
    return _render()


def _environment(service: Mapping[str, Any]) -> dict[str, str]:
    """A service's environment as a dict (compose renders a map or a KEY=VALUE list)."""
    raw = service.get("environment") or {}
    if isinstance(raw, list):
        return dict(item.split("=", 1) for item in raw)
    return {key: "" if value is None else str(value) for key, value in raw.items()}


def _healthcheck_text(service: Mapping[str, Any]) -> str:
    test = service["healthcheck"]["test"]
    return test if isinstance(test, str) else shlex.join(test)


def test_two_services_built_from_the_repos_dockerfiles(config: dict[str, Any]) -> None:
    # Services under a profile (the Sparkplug demonstration broker) start only when asked for;
    # compose v2 leaves them out of `config`, docker-compose 1.x lists them.
    services = {n: s for n, s in config["services"].items() if not s.get("profiles")}
    assert set(services) == {"emulator", "backend"}
    for name, service in services.items():
        dockerfile = Path(service["build"]["context"]) / service["build"]["dockerfile"]
        assert dockerfile.is_file(), f"{name}: {dockerfile} missing"
        assert dockerfile.resolve().is_relative_to(ROOT), f"{name}: built from outside the repo"


def test_backend_image_builds_the_frontend_in_its_own_stage(config: dict[str, Any]) -> None:
    build = config["services"]["backend"]["build"]
    text = (Path(build["context"]) / build["dockerfile"]).read_text(encoding="utf-8")
    stages = [line for line in text.splitlines() if line.upper().startswith("FROM ")]
    assert len(stages) >= 2, "multi-stage: the frontend is built with Node, served by Python"
    assert "npm run build" in text
    assert "COPY --from=frontend" in text


@pytest.mark.parametrize("dockerfile", sorted((ROOT / "docker").glob("*.Dockerfile")), ids=str)
def test_dockerfile_copy_sources_exist(dockerfile: Path) -> None:
    """Every ``COPY`` from the build context names something the repository has."""
    copies = 0
    for line in dockerfile.read_text(encoding="utf-8").splitlines():
        words = line.split()
        if not words or words[0].upper() != "COPY" or any(w.startswith("--from") for w in words):
            continue
        sources = [w for w in words[1:-1] if not w.startswith("--")]
        for source in sources:
            copies += 1
            assert glob.glob(str(ROOT / source)), f"{dockerfile.name}: COPY {source}: not found"
    assert copies > 0


def test_own_network_with_the_emulator_at_a_fixed_address(config: dict[str, Any]) -> None:
    networks = config["networks"]
    emulator = config["services"]["emulator"]
    backend = config["services"]["backend"]
    shared = set(emulator["networks"]) & set(backend["networks"])
    assert shared, "the two services share a network"
    (network,) = shared
    assert network != "default"
    subnet = ipaddress.ip_network(networks[network]["ipam"]["config"][0]["subnet"])
    robot = ipaddress.ip_address(emulator["networks"][network]["ipv4_address"])
    assert robot in subnet
    # The backend talks to the robot as to another host on the cell network.
    assert _environment(backend)["COBOT_HMI_ROBOT_HOST"] == str(robot)
    # The robot's own EtherNet/IP ports: TCP 44818 and UDP 2222, on its own address.
    exposed = {str(port) for port in emulator.get("expose", [])}
    assert {"44818/tcp", "2222/udp"} <= exposed


def test_the_panel_is_published_on_port_8000(config: dict[str, Any]) -> None:
    ports = config["services"]["backend"]["ports"]
    published = set()
    for port in ports:
        if isinstance(port, str):  # "8000:8000" in older renderings
            host, _, target = port.rpartition(":")
            published.add((host.rsplit(":", 1)[-1], target.split("/")[0]))
        else:
            published.add((str(port["published"]), str(port["target"])))
    assert ("8000", "8000") in published
    assert _environment(config["services"]["backend"])["COBOT_HMI_PORT"] == "8000"
    # The robot is not published on the host: only the HMI talks to it.
    assert not config["services"]["emulator"].get("ports")


def test_healthchecks(config: dict[str, Any]) -> None:
    emulator = config["services"]["emulator"]
    backend = config["services"]["backend"]
    assert ":8081/status" in _healthcheck_text(emulator)
    assert "/healthz" in _healthcheck_text(backend)
    assert backend["depends_on"]["emulator"]["condition"] == "service_healthy"


def test_settings_are_real_service_settings(config: dict[str, Any]) -> None:
    known = {env_name(name) for name in ServiceSettings.model_fields}
    environment = _environment(config["services"]["backend"])
    settings = {key for key in environment if key.startswith("COBOT_HMI_")}
    assert settings, "the backend is configured through COBOT_HMI_* variables"
    assert settings <= known, f"unknown settings: {sorted(settings - known)}"


def test_settings_follow_the_environment() -> None:
    rendered = _render({"COBOT_HMI_RPI_MS": "4", "COBOT_HMI_INPUT_ONLY": "true"})
    environment = _environment(rendered["services"]["backend"])
    assert environment["COBOT_HMI_RPI_MS"] == "4"
    assert environment["COBOT_HMI_INPUT_ONLY"] == "true"


def test_commands_are_real_cli_invocations(config: dict[str, Any]) -> None:
    """The emulator's command line parses with the real CLI, and binds where it is reached."""
    command = config["services"]["emulator"]["command"]
    if isinstance(command, str):
        command = shlex.split(command)
    assert command[0] == "cobot-hmi"
    args = build_parser().parse_args(command[1:])
    assert args.verb == "emulator"
    assert args.host == "0.0.0.0"
    assert args.control_port == 8081
