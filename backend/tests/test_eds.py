"""The emulated robot's EDS (CIP Vol 1 Chapter 7), parsed by an independent EDS parser from
PyPI (``eds-pie``, which knows EtherNet/IP's [Assembly] and [Connection Manager] sections) and
checked against the layout and the target's settings: identity, assemblies and sizes, the three
connections, the RPI range. And ``cobot-hmi eds``."""

from __future__ import annotations

import logging
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from cobot_hmi.emulator.eds import eds_text
from cobot_hmi.emulator.target_settings import TargetSettings, default_identity
from cobot_hmi.enip import epath
from cobot_hmi.layout import CONNECTION_POINTS, O2T_ASSEMBLY, T2O_ASSEMBLY

CLI = [sys.executable, "-m", "cobot_hmi.cli"]

APPLICATION_TYPES = {
    "Exclusive Owner": 0x0400_0000,
    "Input Only": 0x0200_0000,
    "Listen Only": 0x0100_0000,
}


class EdsWarnings(logging.Handler):
    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        if record.name.startswith("eds_pie"):
            self.messages.append(record.getMessage())


@pytest.fixture
def parse_eds() -> Iterator[Any]:
    """eds-pie's parser, whose semantic checks log warnings: any warning fails the test.

    eds-pie calls ``logging.basicConfig(level=DEBUG)`` when imported; the root logger's level
    and handlers are put back so the rest of the session logs as before."""
    root = logging.getLogger()
    level, handlers = root.level, list(root.handlers)
    from eds_pie.eds_pie import CIP_EDS

    root.setLevel(level)
    for handler in list(root.handlers):
        if handler not in handlers:
            root.removeHandler(handler)
    warnings = EdsWarnings()
    root.addHandler(warnings)
    try:
        yield CIP_EDS
    finally:
        root.removeHandler(warnings)
    assert warnings.messages == [], warnings.messages


def connections(eds: Any) -> dict[str, dict[str, Any]]:
    """Each Connection entry's fields by eds-pie's field names, keyed by connection name."""
    section = eds.get_section("Connection Manager")
    found: dict[str, dict[str, Any]] = {}
    for keyword, entry in section.entries.items():
        if keyword.startswith("Connection"):
            fields = {field.name: field.value for field in entry.fields}
            found[fields["Connection name string"]] = fields
    return found


def as_int(value: object) -> int:
    return value if isinstance(value, int) else int(str(value), 0)


def test_eds_parses_and_matches_the_layout(parse_eds: Any) -> None:
    eds = parse_eds(eds_text())
    assert eds.protocol == "EtherNetIP"
    identity = TargetSettings().identity
    assert as_int(eds.get_value("Device", "VendCode")) == identity.vendor_id
    assert as_int(eds.get_value("Device", "ProdType")) == identity.device_type
    assert as_int(eds.get_value("Device", "ProdCode")) == identity.product_code
    assert as_int(eds.get_value("Device", "MajRev")) == identity.revision_major
    assert as_int(eds.get_value("Device", "MinRev")) == identity.revision_minor
    assert eds.get_value("Device", "ProdName") == identity.product_name

    points = CONNECTION_POINTS
    sizes = {
        points.t2o: T2O_ASSEMBLY.size_bytes,  # 284
        points.o2t: O2T_ASSEMBLY.size_bytes,  # 20
        points.configuration: 0,
        points.input_only: 0,
        points.listen_only: 0,
    }
    for instance, size in sizes.items():
        assert as_int(eds.get_value("Assembly", f"Assem{instance}", 2)) == size
        data_path = eds.get_value("Assembly", f"Assem{instance}", 1)
        assert bytes.fromhex(data_path) == epath.request_path(epath.CLASS_ASSEMBLY, instance, 3)

    found = connections(eds)
    assert set(found) == set(APPLICATION_TYPES)
    heartbeat = {"Input Only": points.input_only, "Listen Only": points.listen_only}
    for name, fields in found.items():
        transport = as_int(fields["Trigger and transport"])
        assert transport & 0x0F00_0000 == APPLICATION_TYPES[name]
        assert transport & 0xFFFF == 0x0002  # class 1 only
        assert transport & 0x0001_0000  # cyclic
        parameters = as_int(fields["Connection parameters"])
        assert parameters & 0x0F == 0x05  # fixed sizes both ways
        assert (parameters >> 12) & 0x7 == 0  # T→O modeless: no run/idle header
        assert (parameters >> 16) & 0xF == 0x4 and (parameters >> 20) & 0xF == 0x4  # P2P
        assert fields["O2T RPI"] == "Param1" and fields["T2O RPI"] == "Param1"
        assert fields["T2O format"] == f"Assem{points.t2o}"
        assert as_int(fields["T2O size"]) == T2O_ASSEMBLY.size_bytes
        assert fields["Target Config format"] == f"Assem{points.configuration}"
        path = epath.decode_connection_path(bytes.fromhex(fields["Path"]))
        o2t_point, t2o_point = path.points  # consumed, then produced
        assert t2o_point == points.t2o
        assert path.config_instance == points.configuration
        if name == "Exclusive Owner":
            assert (parameters >> 8) & 0x7 == 4  # O→T 32-bit run/idle header
            assert fields["O2T format"] == f"Assem{points.o2t}"
            assert as_int(fields["O2T size"]) == O2T_ASSEMBLY.size_bytes
            assert o2t_point == points.o2t
        else:
            assert (parameters >> 8) & 0x7 == 3  # heartbeat: no data
            assert fields["O2T format"] == f"Assem{heartbeat[name]}"
            assert as_int(fields["O2T size"]) == 0
            assert o2t_point == heartbeat[name]

    rpi = {field.name: field.value for field in eds.get_entry("Params", "Param1").fields}
    settings = TargetSettings()
    assert rpi["Parameter Name"] == "RPI"
    assert as_int(rpi["Data Type"]) == 0xC8  # UDINT
    assert as_int(rpi["Minimum Value"]) == settings.rpi_min_us
    assert as_int(rpi["Maximum Value"]) == settings.rpi_max_us
    assert settings.rpi_min_us <= as_int(rpi["Default Value"]) <= settings.rpi_max_us
    assert as_int(eds.get_value("Capacity", "MaxIOConnections")) == settings.max_connections


def test_eds_follows_the_settings_with_16_bit_instances(parse_eds: Any) -> None:
    settings = TargetSettings(o2t_instance=0x0123, t2o_instance=0x0456, t2o_size=300)
    found = connections(parse_eds(eds_text(settings)))
    owner = found["Exclusive Owner"]
    assert owner["O2T format"] == "Assem291" and owner["T2O format"] == "Assem1110"
    assert as_int(owner["T2O size"]) == 300
    path = epath.decode_connection_path(bytes.fromhex(owner["Path"]))
    assert path.points == (0x0123, 0x0456)


def test_eds_is_stable_and_ascii() -> None:
    text = eds_text()
    assert text == eds_text()
    text.encode("ascii")  # EDS files are ASCII


def test_eds_cli_writes_the_file(tmp_path: Path) -> None:
    out = tmp_path / "cobot.eds"
    result = subprocess.run(
        [*CLI, "eds", "-o", str(out)], capture_output=True, timeout=60, check=False
    )
    assert result.returncode == 0, result.stderr
    assert out.read_text(encoding="ascii") == eds_text()
    result = subprocess.run([*CLI, "eds"], capture_output=True, timeout=60, check=False)
    assert (result.returncode, result.stdout.decode()) == (0, eds_text())
    result = subprocess.run(
        [*CLI, "eds", "-o", str(tmp_path / "missing" / "x.eds")],
        capture_output=True,
        timeout=60,
        check=False,
    )
    assert result.returncode == 1
    assert b"cobot-hmi eds:" in result.stderr


def test_eds_cli_carries_the_models_identity(parse_eds: Any) -> None:
    result = subprocess.run(
        [*CLI, "eds", "--model", "M0609"], capture_output=True, timeout=60, check=False
    )
    assert result.returncode == 0, result.stderr
    eds = parse_eds(result.stdout.decode("ascii"))
    identity = default_identity("M0609")
    assert eds.get_value("Device", "ProdName") == identity.product_name == "Doosan M0609 (emulated)"
    assert as_int(eds.get_value("Device", "ProdCode")) == identity.product_code
