"""docker-compose.yml: the product as a cell of hosts, checked without a Docker engine.

``docker compose config`` (or Debian's standalone ``docker-compose``) parses, validates and
renders the file; these tests read what it rendered: two emulated robots (an M1013 and an
M0609) and the service, built from the repo's Dockerfiles, their own network with each robot at
a fixed address, the service configured for both as ``[[robots]]`` (its cell file, loaded by
the real settings loader), the panel published on port 8000, health checks, and settings that
are real ``COBOT_HMI_*`` names. The Dockerfiles' ``COPY`` sources are checked against the
repository too. Only a machine without the docker client skips (no engine is needed:
``config`` only parses).
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
from cobot_hmi.service.config.loading import env_name, load_settings
from cobot_hmi.service.setting_fields import CONFIG_ENV
from cobot_hmi.settings import HmiSettings

ROOT = Path(__file__).resolve().parents[2]
COMPOSE_FILE = ROOT / "docker-compose.yml"
DOCKER = shutil.which("docker")
EMULATORS = {"m1013": "M1013", "m0609": "M0609"}
"""The cell's emulated robots: compose service (and robot name) → arm."""

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
    assert set(services) == {*EMULATORS, "backend"}
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


def _emulator_args(service: Mapping[str, Any]) -> Any:
    """An emulator service's command line, parsed by the real CLI."""
    command = service["command"]
    if isinstance(command, str):
        command = shlex.split(command)
    assert command[0] == "cobot-hmi"
    return build_parser().parse_args(command[1:])


def _mounted_file(service: Mapping[str, Any], target: str) -> Path:
    """The host file a service mounts at ``target`` (short or long volume syntax)."""
    for volume in service.get("volumes", []):
        if isinstance(volume, dict):
            source, inside = volume.get("source"), volume.get("target")
        else:
            source, inside = [*volume.split(":"), ""][:2]
        if inside == target:
            return Path(str(source))
    pytest.fail(f"nothing is mounted at {target}")


def test_own_network_with_each_robot_at_a_fixed_address(config: dict[str, Any]) -> None:
    networks = config["networks"]
    backend = config["services"]["backend"]
    addresses = {}
    for name in EMULATORS:
        emulator = config["services"][name]
        shared = set(emulator["networks"]) & set(backend["networks"])
        assert shared, f"{name} and the backend share a network"
        (network,) = shared
        assert network != "default"
        subnet = ipaddress.ip_network(networks[network]["ipam"]["config"][0]["subnet"])
        robot = ipaddress.ip_address(emulator["networks"][network]["ipv4_address"])
        assert robot in subnet
        addresses[name] = str(robot)
        # The robot's own EtherNet/IP ports: TCP 44818 and UDP 2222, on its own address.
        exposed = {str(port) for port in emulator.get("expose", [])}
        assert {"44818/tcp", "2222/udp"} <= exposed
    assert len(set(addresses.values())) == len(EMULATORS), "each robot is a host of its own"


def test_the_service_is_configured_for_both_robots(config: dict[str, Any]) -> None:
    """The backend's settings, loaded as the service loads them (its environment over its
    cell file): the two robots as ``[[robots]]``, each at its emulator's address, M1013 first."""
    backend = config["services"]["backend"]
    environment = _environment(backend)
    cell = _mounted_file(backend, environment["COBOT_HMI_CONFIG"])
    assert cell.is_file(), f"{cell} missing"
    assert cell.resolve().is_relative_to(ROOT)
    assert "[[robots]]" in cell.read_text(encoding="utf-8")
    settings = load_settings(
        {}, {k: v for k, v in environment.items() if k != "COBOT_HMI_CONFIG"}, cell
    )
    addresses = {
        name: config["services"][name]["networks"]["cell"]["ipv4_address"] for name in EMULATORS
    }
    assert [(r.name, r.host, r.tcp_port) for r in settings.cell.robots] == [
        (name, addresses[name], 44818) for name in EMULATORS
    ]
    assert all(r.mode == "exclusive-owner" for r in settings.cell.robots)
    # Each robot's arm is the one its emulator simulates.
    assert {n: _emulator_args(config["services"][n]).model for n in EMULATORS} == EMULATORS
    # The service waits for both robots to be up.
    assert set(backend["depends_on"]) == set(EMULATORS)


def test_one_real_robot_instead_of_the_cell() -> None:
    """COBOT_HMI_ROBOT_HOST replaces the cell file's robots (the highest source wins)."""
    rendered = _render({"COBOT_HMI_ROBOT_HOST": "192.0.2.10"})
    backend = rendered["services"]["backend"]
    environment = _environment(backend)
    cell = _mounted_file(backend, environment["COBOT_HMI_CONFIG"])
    settings = load_settings(
        {}, {k: v for k, v in environment.items() if k != "COBOT_HMI_CONFIG"}, cell
    )
    assert [(r.name, r.host) for r in settings.cell.robots] == [("robot", "192.0.2.10")]


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
    # The robots are not published on the host: only the HMI talks to them.
    for name in EMULATORS:
        assert not config["services"][name].get("ports")


def test_healthchecks(config: dict[str, Any]) -> None:
    backend = config["services"]["backend"]
    for name in EMULATORS:
        assert ":8081/status" in _healthcheck_text(config["services"][name])
        assert backend["depends_on"][name]["condition"] == "service_healthy"
    assert "/healthz" in _healthcheck_text(backend)


def test_settings_are_real_service_settings(config: dict[str, Any]) -> None:
    known = {env_name(name) for name in HmiSettings.setting_keys()} | {CONFIG_ENV}
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
    """Each emulator's command line parses with the real CLI, and binds where it is reached."""
    for name, model in EMULATORS.items():
        args = _emulator_args(config["services"][name])
        assert args.verb == "emulator"
        assert args.host == "0.0.0.0"
        assert args.control_port == 8081
        assert args.model == model
