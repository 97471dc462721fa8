"""Explicit O→T data is what is sent (issue 27, part 1): with ``o2t_data`` (``scan --o2t-hex``)
at the robot layout's sizes, the bumpless takeover never rebuilds the command image from the
first T→O frame; every O→T packet the emulator receives carries the given bytes until the
connection ends. The emulator says what it received: each connection's ``o2t_data_hex`` (the
last new packet's data, idle too) and ``o2t_data_changes`` (new packets whose data differed
from the one before).

The robot's outputs are set to something else first, so a takeover would show.
"""

from __future__ import annotations

import asyncio
import json
import signal
import sys

from cobot_hmi.codec import command_from_json, encode_command
from cobot_hmi.emulator.connections import ConnectionInfo
from cobot_hmi.emulator.static_robot import StaticRobot
from cobot_hmi.emulator.target import Target
from cobot_hmi.scanner.originator import Originator, OriginatorSettings

DEADLINE_S = 30.0
"""A generous functional deadline, never a timing figure."""

ROBOT_OUTPUTS = command_from_json(
    {
        "controlbox_do": {"0": True, "15": True},
        "tool_do": {"5": True},
        "analog_output_type": [1, 0],
        "analog_output": [2.5, 12.0],
    }
)
"""What the robot does when the connection opens: what a takeover would copy into O→T."""
GIVEN = encode_command(
    command_from_json(
        {
            "controlbox_do": {"1": True, "2": True, "9": True},
            "tool_do": {"0": True},
            "analog_output_type": [0, 1],
            "analog_output": [7.25, 3.5],
            "bit_input_registers": {"7": True, "63": True},
        }
    )
)
"""20 bytes (the robot layout's O→T size), bytes 0–11 unlike the robot's outputs."""


async def eventually_owner(target: Target, packets_in: int) -> ConnectionInfo:
    """The owner connection's snapshot once the emulator received ``packets_in`` O→T packets."""
    loop = asyncio.get_running_loop()
    end = loop.time() + DEADLINE_S
    while True:
        owners = [c for c in target.connections() if c.kind == "owner"]
        if owners and owners[0].packets_in >= packets_in:
            return owners[0]
        assert loop.time() < end, "the emulator did not receive the O→T packets in time"
        await asyncio.sleep(0.02)


async def test_originator_sends_the_given_data_in_every_packet(
    target: Target, robot: StaticRobot, robot_host: str, plc_host: str
) -> None:
    robot.consume_command(ROBOT_OUTPUTS, 0.0)
    assert encode_command(ROBOT_OUTPUTS)[:12] != GIVEN[:12]
    originator = Originator(
        OriginatorSettings(
            robot_host=robot_host,
            tcp_port=target.tcp_port,
            local_host=plc_host,
            rpi_us=10_000,
            o2t_data=GIVEN,
        )
    )
    await originator.start()
    try:
        assert await originator.wait_connected(DEADLINE_S)
        # Far past the first frame (the takeover came with it, from the third packet on).
        await eventually_owner(target, 50)
        assert originator.latest is not None
        assert originator.latest[0].controlbox_do == ROBOT_OUTPUTS.controlbox_do
        last = await eventually_owner(target, 100)
        assert originator.o2t_data == GIVEN
    finally:
        await originator.stop()
    assert last.o2t_data_hex == GIVEN.hex()
    assert last.o2t_data_changes == 0, "every O→T packet carried the given bytes"
    assert last.run is False
    assert robot.command_image() == ROBOT_OUTPUTS, "sent idle: the robot applied nothing"


async def test_scan_verb_sends_o2t_hex_in_every_packet(
    target: Target, robot: StaticRobot, robot_host: str, plc_host: str
) -> None:
    """``scan --o2t-hex`` at the robot's sizes, run until interrupted: the emulator's last view
    of the connection (taken after 100 packets) saw the given data and no other."""
    robot.consume_command(ROBOT_OUTPUTS, 0.0)
    process = await asyncio.create_subprocess_exec(
        sys.executable,
        "-m",
        "cobot_hmi.cli",
        "scan",
        robot_host,
        "--port",
        str(target.tcp_port),
        "--local-host",
        plc_host,
        "--o2t-hex",
        GIVEN.hex(),
        "--stats",
        stdout=asyncio.subprocess.PIPE,
        stderr=asyncio.subprocess.PIPE,
    )
    try:
        last = await eventually_owner(target, 100)
        process.send_signal(signal.SIGINT)
        stdout, stderr = await asyncio.wait_for(process.communicate(), DEADLINE_S)
    finally:
        if process.returncode is None:
            process.kill()
            await process.communicate()
    assert process.returncode == 0, stderr.decode()
    assert last.o2t_data_hex == GIVEN.hex()
    assert last.o2t_data_changes == 0, "every O→T packet carried --o2t-hex"
    assert last.run is False
    summary = json.loads(stdout.decode().splitlines()[-1])["summary"]
    assert summary["state"] == "connected"
    assert summary["slow_target"] is None, "the emulator keeps its grant"
    assert robot.command_image() == ROBOT_OUTPUTS


async def test_scan_help_says_it_sends_idle() -> None:
    process = await asyncio.create_subprocess_exec(
        sys.executable,
        "-m",
        "cobot_hmi.cli",
        "scan",
        "--help",
        stdout=asyncio.subprocess.PIPE,
        stderr=asyncio.subprocess.PIPE,
    )
    stdout, _ = await asyncio.wait_for(process.communicate(), DEADLINE_S)
    text = " ".join(stdout.decode().split())
    assert process.returncode == 0
    assert "sends IDLE from start to end" in text
    assert "does not apply its data to its outputs" in text
    assert "in every O→T packet as given" in text
    assert "slow_target" in text and "late" in text and "gaps" in text
