"""st-ethernet-ip's ``IO.Scanner`` (npm, an independent alpha class 1 scanner) holds a class 1
connection to our emulator for more than 3 s, and the bytes it writes reach the emulator's
command image (issue 3, "Tests"). ``make test`` installs it (``npm ci`` in tests/peers).

It connects to TCP 44818 and binds UDP 2222 without SO_REUSEADDR, so the
emulator gets the test's own ``robot_host`` with the standard ports, and the scanner ``plc_host``.
"""

from __future__ import annotations

import asyncio
import json
import shutil
from pathlib import Path

from cobot_hmi.codec import command_from_json, decode_frame, encode_command
from cobot_hmi.emulator.connections import ConnectionInfo
from cobot_hmi.emulator.static_robot import StaticRobot
from cobot_hmi.emulator.target import Target
from cobot_hmi.emulator.target_settings import TargetSettings

PEERS = Path(__file__).parent / "peers"


async def _connections_while(
    process: asyncio.subprocess.Process, target: Target
) -> list[ConnectionInfo]:
    """The target's connections once one is running (its O→T data has come with the run bit:
    the Forward Open alone makes the row), or what it has when the peer has ended."""
    deadline = asyncio.get_running_loop().time() + 60.0
    while True:
        during = target.connections()
        if any(c.run for c in during) or process.returncode is not None:
            return during
        if asyncio.get_running_loop().time() > deadline:
            return during
        await asyncio.sleep(0.05)


async def test_st_ethernet_ip_scanner_holds_a_connection(robot_host: str, plc_host: str) -> None:
    node = shutil.which("node")
    assert node, "node missing: `make test` needs nodejs"
    assert (PEERS / "node_modules" / "st-ethernet-ip").is_dir(), "run `make peers` (npm ci)"
    robot = StaticRobot()
    target = Target(TargetSettings(host=robot_host), robot)
    image = command_from_json(
        {
            "controlbox_do": {"0": True, "9": True},
            "tool_do": {"2": True},
            "bit_input_registers": {"5": True, "63": True},
        }
    )
    await target.start()
    try:
        process = await asyncio.create_subprocess_exec(
            node,
            str(PEERS / "st_scanner.js"),
            robot_host,
            plc_host,
            "4.5",
            "10",
            encode_command(image).hex(),
            cwd=PEERS,
            stdout=asyncio.subprocess.PIPE,
            stderr=asyncio.subprocess.PIPE,
        )
        # While the peer holds its connection (4.5 s from when node has started, which a busy
        # machine may take seconds to do): the target's table, seen as soon as it has a row.
        during = await _connections_while(process, target)
        out, err = await asyncio.wait_for(process.communicate(), 30)
    finally:
        await target.stop()
    assert process.returncode == 0, err.decode()
    events = [json.loads(line) for line in out.decode().splitlines()]
    summary = events[-1]
    assert summary["event"] == "summary", events
    assert summary["connected"] is True and summary["disconnects"] == 0, events
    assert summary["connected_ms"] >= 3000, events
    assert [c.kind for c in during] == ["owner"]
    assert during[0].run is True
    assert robot.command_image() == image  # its O→T bytes reached the command image
    frame = decode_frame(bytes.fromhex(summary["input_hex"]))
    assert frame.robot_state == 13
    assert frame.controlbox_do[9] is True  # and the robot's actual outputs followed
