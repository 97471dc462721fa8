"""Layer: emulator. Imports the layout, ``cobot_hmi.enip`` (connection paths) and the
emulator's settings; no I/O.

The Electronic Data Sheet (EDS, CIP Vol 1 Chapter 7; EtherNet/IP specifics Vol 2 Chapter 7) of
the emulated robot's adapter: what a PLC programming tool imports to add the robot to a
project. Everything in it comes from one place, ``TargetSettings`` (whose defaults come from
the layout): the identity, the assemblies with their instances and sizes, the three
connections the target accepts (exclusive owner, input-only, listen-only) and the RPI range.
The text is stable (no clock in it), so the same settings always give the same bytes.

Each Connection entry (Vol 1 §7-3.6.11) gives:

- trigger and transport: bits 0–15 the transport classes (bit 1: class 1), bit 16 cyclic,
  bits 24–27 the application type (24 listen-only, 25 input-only, 26 exclusive owner);
- connection parameters: bits 0–3 fixed sizes (bit 0 O→T, bit 2 T→O); bits 8–10 the O→T
  real-time format (4: 32-bit run/idle header, 3: heartbeat), bits 12–14 the T→O one (0:
  modeless, no header, as our T→O); bits 16–19 / 20–23 the O→T / T→O connection types (bit 18
  / 22: point-to-point; this target produces no multicast); bits 24–27 / 28–31 the priorities
  (bit 26 / 30: scheduled);
- O→T then T→O: RPI (Param1, the accepted range), data size in bytes (the sequence count and
  the run/idle header come on top, from the parameters above), the assembly;
- the configuration assembly (size 0), the name, the help string and the connection path.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

from cobot_hmi.emulator.target_settings import DOOSAN_VENDOR_ID, TargetSettings
from cobot_hmi.enip import epath
from cobot_hmi.layout import LAYOUT_VERSION

DEFAULT_RPI_US: Final = 10_000
"""The RPI a tool proposes (docs/operations.md: 10 ms is plenty for an HMI)."""
EDS_DATE: Final = "11-24-2026"
"""CreateDate / ModDate (mm-dd-yyyy): fixed, so the file is the same whenever it is made."""
EDS_TIME: Final = "00:00:00"

_CLASS_1: Final = 0x0000_0002
_CYCLIC: Final = 0x0001_0000
_LISTEN_ONLY: Final = 0x0100_0000
_INPUT_ONLY: Final = 0x0200_0000
_EXCLUSIVE_OWNER: Final = 0x0400_0000

_FIXED_SIZES: Final = 0x0000_0005  # O→T fixed, T→O fixed
_O2T_RUN_IDLE: Final = 0x0000_0400  # real-time format 4: 32-bit run/idle header
_O2T_HEARTBEAT: Final = 0x0000_0300  # real-time format 3: heartbeat (no data)
_T2O_MODELESS: Final = 0x0000_0000
_POINT_TO_POINT_BOTH: Final = 0x0044_0000  # O→T bit 18, T→O bit 22
_SCHEDULED_BOTH: Final = 0x4400_0000  # O→T bit 26, T→O bit 30

_PRODUCT_TYPE_NAMES: Final = {0x00: "Generic Device", 0x2B: "Generic Device (keyable)"}


@dataclass(frozen=True, slots=True)
class EdsAssembly:
    instance: int
    name: str
    size_bytes: int


@dataclass(frozen=True, slots=True)
class EdsConnection:
    """One Connection entry, in the terms a test checks against the layout."""

    name: str
    application_type: int
    o2t_format: int
    o2t_size_bytes: int
    o2t_instance: int
    t2o_size_bytes: int
    t2o_instance: int
    config_instance: int

    @property
    def trigger_and_transport(self) -> int:
        return self.application_type | _CYCLIC | _CLASS_1

    @property
    def parameters(self) -> int:
        return (
            _SCHEDULED_BOTH | _POINT_TO_POINT_BOTH | _T2O_MODELESS | self.o2t_format | _FIXED_SIZES
        )

    @property
    def path(self) -> bytes:
        return epath.connection_path(self.config_instance, self.o2t_instance, self.t2o_instance)


def eds_assemblies(settings: TargetSettings) -> tuple[EdsAssembly, ...]:
    """The assemblies the EDS declares, as the target serves them."""
    return (
        EdsAssembly(settings.t2o_instance, "Robot to PLC", settings.t2o_size),
        EdsAssembly(settings.o2t_instance, "PLC to Robot", settings.o2t_size),
        EdsAssembly(settings.config_instance, "Configuration", 0),
        EdsAssembly(settings.input_only_instance, "Input-only heartbeat", 0),
        EdsAssembly(settings.listen_only_instance, "Listen-only heartbeat", 0),
    )


def eds_connections(settings: TargetSettings) -> tuple[EdsConnection, ...]:
    """The connections the target accepts (``emulator.connections.admit``)."""
    s = settings
    return (
        EdsConnection(
            "Exclusive Owner",
            _EXCLUSIVE_OWNER,
            _O2T_RUN_IDLE,
            s.o2t_size,
            s.o2t_instance,
            s.t2o_size,
            s.t2o_instance,
            s.config_instance,
        ),
        EdsConnection(
            "Input Only",
            _INPUT_ONLY,
            _O2T_HEARTBEAT,
            0,
            s.input_only_instance,
            s.t2o_size,
            s.t2o_instance,
            s.config_instance,
        ),
        EdsConnection(
            "Listen Only",
            _LISTEN_ONLY,
            _O2T_HEARTBEAT,
            0,
            s.listen_only_instance,
            s.t2o_size,
            s.t2o_instance,
            s.config_instance,
        ),
    )


def _quoted(text: str) -> str:
    ascii_text = text.encode("ascii", "replace").decode("ascii")  # EDS strings are ASCII
    return '"' + ascii_text.replace('"', "'") + '"'


def _hex_path(path: bytes) -> str:
    return '"' + " ".join(f"{byte:02X}" for byte in path) + '"'


def _vendor_name(vendor_id: int) -> str:
    """The vendor's name as ODVA lists it when the emulator identifies as Doosan (its default)."""
    return "Doosan Robotics" if vendor_id == DOOSAN_VENDOR_ID else "cobot-hmi (emulated adapter)"


def eds_text(settings: TargetSettings | None = None) -> str:
    """The EDS file of the target ``settings`` describe (the emulator's defaults if none)."""
    s = settings if settings is not None else TargetSettings()
    lines = [*_device_sections(s), *_assembly_section(s), *_connection_section(s)]
    lines += [
        "",
        "[Capacity]",
        f"        MaxIOConnections = {s.max_connections};",
        "",
    ]
    return "\n".join(lines)


def _device_sections(s: TargetSettings) -> list[str]:
    """The file's header and its [File], [Device], [Device Classification] and [Params]."""
    identity = s.identity
    default_rpi_us = min(max(DEFAULT_RPI_US, s.rpi_min_us), s.rpi_max_us)
    product_type = _PRODUCT_TYPE_NAMES.get(identity.device_type, "Generic Device")
    return [
        "$ Electronic Data Sheet (CIP Vol 1 Chapter 7) of the emulated Doosan robot's",
        "$ EtherNet/IP adapter. Generated by `cobot-hmi eds` from the layout and the",
        "$ emulator's settings; do not edit (docs/operations.md).",
        "",
        "[File]",
        f"        DescText = {_quoted('cobot-hmi emulated Doosan robot adapter')};",
        f"        CreateDate = {EDS_DATE};",
        f"        CreateTime = {EDS_TIME};",
        f"        ModDate = {EDS_DATE};",
        f"        ModTime = {EDS_TIME};",
        f"        Revision = {LAYOUT_VERSION}.0;",
        "",
        "[Device]",
        f"        VendCode = {identity.vendor_id};",
        f"        VendName = {_quoted(_vendor_name(identity.vendor_id))};",
        f"        ProdType = {identity.device_type};",
        f"        ProdTypeStr = {_quoted(product_type)};",
        f"        ProdCode = {identity.product_code};",
        f"        MajRev = {identity.revision_major};",
        f"        MinRev = {identity.revision_minor};",
        f"        ProdName = {_quoted(identity.product_name)};",
        f"        Catalog = {_quoted('cobot-hmi emulator')};",
        "",
        "[Device Classification]",
        "        Class1 = EtherNetIP;",
        "",
        "[Params]",
        "        Param1 =",
        "                0,                      $ reserved",
        "                ,,                      $ link path size, link path",
        "                0x0000,                 $ descriptor",
        "                0xC8,                   $ data type: UDINT",
        "                4,                      $ data size",
        '                "RPI",                  $ name',
        '                "microsecond",          $ units',
        '                "Requested Packet Interval", $ help',
        f"                {s.rpi_min_us},{s.rpi_max_us},{default_rpi_us},"
        "  $ minimum, maximum, default",
        "                ,,,,                    $ scaling",
        "                ,,,,                    $ links",
        "                ;                       $ decimal places",
        "",
    ]


def _assembly_section(s: TargetSettings) -> list[str]:
    lines = [
        "[Assembly]",
        f"        Object_Name = {_quoted('Assembly Object')};",
        "        Object_Class_Code = 0x04;",
    ]
    for assembly in eds_assemblies(s):
        data_path = epath.request_path(epath.CLASS_ASSEMBLY, assembly.instance, 3)
        lines.append(
            f"        Assem{assembly.instance} = {_quoted(assembly.name)}, "
            f"{_hex_path(data_path)}, {assembly.size_bytes}, 0x0000, , ;"
        )
    return lines


def _connection_section(s: TargetSettings) -> list[str]:
    lines = [
        "",
        "[Connection Manager]",
        f"        Object_Name = {_quoted('Connection Manager Object')};",
        "        Object_Class_Code = 0x06;",
    ]
    for number, connection in enumerate(eds_connections(s), start=1):
        lines += [
            f"        Connection{number} =",
            f"                0x{connection.trigger_and_transport:08X},  $ trigger and transport",
            f"                0x{connection.parameters:08X},  $ connection parameters",
            f"                Param1,{connection.o2t_size_bytes},Assem{connection.o2t_instance},"
            "  $ O->T RPI, size, format",
            f"                Param1,{connection.t2o_size_bytes},Assem{connection.t2o_instance},"
            "  $ T->O RPI, size, format",
            "                ,,  $ proxy config size, format",
            f"                0,Assem{connection.config_instance},  $ target config size, format",
            f"                {_quoted(connection.name)},  $ connection name",
            '                "",  $ help string',
            f"                {_hex_path(connection.path)};  $ path",
        ]
    return lines


__all__ = ["EdsAssembly", "EdsConnection", "eds_assemblies", "eds_connections", "eds_text"]
