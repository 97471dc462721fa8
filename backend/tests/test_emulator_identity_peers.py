"""The emulator's identity and its connection IDs as peers see them (issue 37, item 11), on
loopback against the real target.

- pycomm3 (an independent CIP client from PyPI, with ODVA's vendor list inside) reads the
  Identity object: vendor 1573, Doosan Robotics, as the robot the emulator stands in for
  (before: 0xFFFE), and attribute 8, State, which was "attribute not supported" while
  ListIdentity said 3 (operational); both now say the same. The vendor stays settable.
- Two starts of the target give different first O→T connection IDs (before: 0xD82C07CD after
  every start, from a fixed seed), so an originator cannot take a restarted target's new
  connection for the old one.
"""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator
from typing import Any

import pytest
from pycomm3 import CIPDriver, ClassCode, Services
from pycomm3.cip.data_types import UINT, USINT
from pycomm3.custom_types import ModuleIdentityObject

from cobot_hmi.emulator.static_robot import StaticRobot
from cobot_hmi.emulator.target import Target
from cobot_hmi.emulator.target_settings import DOOSAN_VENDOR_ID, TargetSettings, default_identity
from cobot_hmi.scanner.originator import Originator, OriginatorSettings

pytestmark = pytest.mark.timeout(120)

OPERATIONAL = 3
"""Identity attribute 8, State: 3 = operational (CIP Vol 1 §5-2.2)."""


@pytest.fixture
async def target(robot_host: str) -> AsyncIterator[Target]:
    emulator = Target(TargetSettings(host=robot_host, tcp_port=0), StaticRobot())
    await emulator.start()
    try:
        yield emulator
    finally:
        await emulator.stop()


UNCONNECTED: dict[str, Any] = {"connected": False, "unconnected_send": False, "route_path": False}
"""UCMM requests straight to the target (no class 3 connection, no routing: not a ControlLogix)."""


def _identity_by_pycomm3(host: str, port: int) -> dict[str, Any]:
    """What pycomm3 reads of the Identity object (class 1, instance 1) and from ListIdentity."""
    path = f"{host}:{port}"
    with CIPDriver(path) as driver:

        def single(attribute: int, data_type: Any) -> Any:
            tag = driver.generic_message(
                service=Services.get_attribute_single,
                class_code=ClassCode.identity_object,
                instance=1,
                attribute=attribute,
                data_type=data_type,
                name=f"identity attribute {attribute}",
                **UNCONNECTED,
            )
            assert tag.error is None, tag.error
            return tag.value

        everything = driver.generic_message(
            service=Services.get_attributes_all,
            class_code=ClassCode.identity_object,
            instance=1,
            data_type=ModuleIdentityObject,
            name="identity",
            **UNCONNECTED,
        )
        assert everything.error is None, everything.error
        read = {"vendor": single(1, UINT), "state": single(8, USINT), "all": everything.value}
    listed = CIPDriver.list_identity(path)
    assert listed is not None
    return {**read, "listed": listed}


async def test_pycomm3_reads_doosans_vendor_and_the_state(target: Target, robot_host: str) -> None:
    seen = await asyncio.to_thread(_identity_by_pycomm3, robot_host, target.tcp_port)
    assert seen["vendor"] == DOOSAN_VENDOR_ID == 1573
    assert seen["all"]["vendor"] == "Doosan Robotics"  # pycomm3's copy of ODVA's list
    assert seen["all"]["product_code"] == target.identity.product_code
    assert seen["listed"]["vendor"] == "Doosan Robotics"
    assert seen["state"] == seen["listed"]["state"] == OPERATIONAL


async def test_the_vendor_is_settable(robot_host: str) -> None:
    settings = TargetSettings(
        host=robot_host, tcp_port=0, identity=default_identity(vendor_id=0xFFFE)
    )
    emulator = Target(settings, StaticRobot())
    await emulator.start()
    try:
        seen = await asyncio.to_thread(_identity_by_pycomm3, robot_host, emulator.tcp_port)
    finally:
        await emulator.stop()
    assert seen["vendor"] == 0xFFFE
    with pytest.raises(ValueError, match="vendor_id"):
        default_identity(vendor_id=0x10000)


async def _first_o2t_connection_id(robot_host: str, plc_host: str) -> int:
    """A fresh target's O→T connection ID for its first connection (an originator's)."""
    target = Target(TargetSettings(host=robot_host, tcp_port=0), StaticRobot())
    await target.start()
    try:
        originator = Originator(
            OriginatorSettings(robot_host, target.tcp_port, local_host=plc_host, rpi_us=50_000)
        )
        await originator.start()
        try:
            assert await originator.wait_connected(10)
            (connection,) = target.connections()
            return connection.o2t_connection_id
        finally:
            await originator.stop()
    finally:
        await target.stop()


async def test_two_starts_choose_different_first_connection_ids(
    robot_host: str, plc_host: str
) -> None:
    first = await _first_o2t_connection_id(robot_host, plc_host)
    second = await _first_o2t_connection_id(robot_host, plc_host)
    # Equal by chance once in 2^32 runs; before, equal every time (0xD82C07CD).
    assert first != second, f"0x{first:08X} twice"
