"""Scanning any adapter (issue 11, "Scanning any adapter"): the emulator configured as a
32/32-byte adapter on other instances, scanned by the originator and by the ``scan`` and
``probe`` verbs: the Forward Open's sizes, every O→T packet's size and the T→O data as hex all
follow ``--sizes``; decoding to the robot's frame happens only at the layout's size. And
``scan`` without ``--local-host`` beside another process holding UDP 2222 on another loopback
address.
"""

from __future__ import annotations

import asyncio
import json
import socket
import sys
from collections.abc import AsyncIterator, Callable

import pytest

from cobot_hmi.emulator.static_robot import StaticRobot
from cobot_hmi.emulator.target import Target
from cobot_hmi.emulator.target_settings import TargetSettings
from cobot_hmi.scanner.originator import ConnectionState, Originator, OriginatorSettings

DEADLINE_S = 10.0
INSTANCES = (103, 102, 101)  # configuration, O→T, T→O: not the robot's


async def eventually(check: Callable[[], bool], timeout_s: float = DEADLINE_S) -> None:
    """Wait until ``check()`` holds (a generous functional deadline, not a timing figure)."""
    loop = asyncio.get_running_loop()
    end = loop.time() + timeout_s
    while not check():
        assert loop.time() < end, "condition not reached in time"
        await asyncio.sleep(0.01)


@pytest.fixture
async def adapter(robot_host: str) -> AsyncIterator[Target]:
    """The emulator as a 32/32-byte adapter on instances 103/102/101."""
    cfg, o2t, t2o = INSTANCES
    settings = TargetSettings(
        host=robot_host,
        tcp_port=0,
        o2t_size=32,
        t2o_size=32,
        config_instance=cfg,
        o2t_instance=o2t,
        t2o_instance=t2o,
    )
    emulator = Target(settings, StaticRobot())
    await emulator.start()
    try:
        yield emulator
    finally:
        await emulator.stop()


async def _run_cli(*args: str, timeout_s: float = 60.0) -> tuple[int, str, str]:
    process = await asyncio.create_subprocess_exec(
        sys.executable,
        "-m",
        "cobot_hmi.cli",
        *args,
        stdout=asyncio.subprocess.PIPE,
        stderr=asyncio.subprocess.PIPE,
    )
    stdout, stderr = await asyncio.wait_for(process.communicate(), timeout_s)
    assert process.returncode is not None
    return process.returncode, stdout.decode(), stderr.decode()


async def test_originator_holds_a_32_32_adapter_with_raw_data(
    adapter: Target, robot_host: str, plc_host: str
) -> None:
    """Sizes as data: the target accepts the Forward Open (38/34 bytes), every O→T packet it
    receives has 32 data bytes (it counts no malformed one), T→O arrives as 32-byte data on
    ``on_data``, and a change of the O→T data reaches the wire."""
    cfg, o2t, t2o = INSTANCES
    data: list[bytes] = []
    settings = OriginatorSettings(
        robot_host=robot_host,
        tcp_port=adapter.tcp_port,
        local_host=plc_host,
        rpi_us=10_000,
        config_instance=cfg,
        o2t_instance=o2t,
        t2o_instance=t2o,
        o2t_size=32,
        t2o_size=32,
        o2t_data=b"\x01\x02",
    )
    originator = Originator(settings, on_data=lambda payload, at, seq: data.append(payload))
    assert originator.o2t_data == b"\x01\x02" + bytes(30)
    await originator.start()
    try:
        assert await originator.wait_connected(DEADLINE_S)
        (info,) = adapter.connections()
        await eventually(lambda: adapter.connections()[0].packets_in >= 10)
        originator.set_o2t_data(bytes(range(32)))
        assert originator.o2t_data == bytes(range(32))
        with pytest.raises(ValueError, match="33 bytes"):
            originator.set_o2t_data(bytes(33))
        await eventually(lambda: len(data) >= 20)
        count = adapter.connections()[0].packets_in
        await eventually(lambda: adapter.connections()[0].packets_in >= count + 10)
        assert adapter.assembly.data(o2t) == bytes(32), "idle: the O→T instance keeps its data"
        originator.set_run(True)
        await eventually(lambda: adapter.assembly.data(o2t) == bytes(range(32)))
        stats = originator.stats()
    finally:
        await originator.stop()
    assert info.o2t_connection_id != 0
    assert adapter.counters.udp_malformed == 0, "every O→T packet had 32 bytes + headers"
    assert all(len(payload) == 32 for payload in data)
    assert originator.latest is None, "no robot frame is made of 32 bytes"
    assert originator.latest_data is not None and len(originator.latest_data[0]) == 32
    assert stats.state is ConnectionState.CONNECTED
    assert stats.malformed == 0 and stats.foreign == 0 and stats.gaps == 0


async def test_scan_verb_against_a_32_32_adapter(
    adapter: Target, robot_host: str, plc_host: str
) -> None:
    common = (robot_host, "--port", str(adapter.tcp_port), "--local-host", plc_host)
    instances = ",".join(map(str, INSTANCES))
    code, out, err = await _run_cli(
        "scan",
        *common,
        "--sizes",
        "32,32",
        "--instances",
        instances,
        "--o2t-hex",
        "0102",
        "--seconds",
        "1.5",
    )
    assert code == 0, err
    lines = [json.loads(line) for line in out.splitlines()]
    data_lines = [line for line in lines if "data_hex" in line]
    assert len(data_lines) > 10
    assert all(len(line["data_hex"]) == 64 for line in data_lines)
    assert all(set(line) == {"t", "seq", "data_hex"} for line in data_lines)
    assert [line["seq"] for line in data_lines] == list(range(1, len(data_lines) + 1))
    summary = lines[-1]["summary"]
    assert summary["state"] == "connected"
    assert summary["malformed"] == 0 and summary["gaps"] == 0 and summary["foreign"] == 0
    assert summary["packets_out"] > 10
    assert adapter.counters.udp_malformed == 0, "no O→T packet of the wrong size"
    assert adapter.counters.forward_open_refusals == 0

    code, out, err = await _run_cli("scan", *common, "--o2t-hex", "zz")
    assert code == 2 and "hexadecimal" in err
    code, out, err = await _run_cli(
        "scan", *common, "--sizes", "32,32", "--instances", instances, "--o2t-hex", "00" * 33
    )
    assert code == 1 and "33 bytes" in err


async def test_scan_verb_raw_at_the_robot_size(
    target: Target, robot_host: str, plc_host: str
) -> None:
    common = (robot_host, "--port", str(target.tcp_port), "--local-host", plc_host)
    code, out, err = await _run_cli("scan", *common, "--raw", "--seconds", "1")
    assert code == 0, err
    lines = [json.loads(line) for line in out.splitlines()]
    data_lines = [line for line in lines if "data_hex" in line]
    assert data_lines and all(len(line["data_hex"]) == 2 * 284 for line in data_lines)
    assert not any("frame" in line for line in lines)


async def test_probe_verb_against_a_32_32_adapter(adapter: Target, robot_host: str) -> None:
    """The T→O data as hex, no frame decoded from 32 bytes, and ``--sizes`` checked against the
    T→O assembly's size."""
    common = ("probe", robot_host, "--port", str(adapter.tcp_port))
    points = ("--o2t-instance", str(INSTANCES[1]), "--t2o-instance", str(INSTANCES[2]))
    code, out, err = await _run_cli(*common, *points)
    assert code == 0, err
    result = json.loads(out)
    assert result["assembly_sizes"][str(INSTANCES[2])] == 32
    assert result["assembly_sizes"][str(INSTANCES[1])] == 32, "the O→T instance's own size"
    assert len(result["t2o_data_hex"]) == 64
    assert result["t2o_frame"] is None
    assert "t2o_frame_error" not in result
    code, out, err = await _run_cli(*common, *points, "--sizes", "32,284")
    assert code == 1, err
    assert json.loads(out)["sizes_match"] is False
    code, out, err = await _run_cli(*common, *points, "--sizes", "32,32")
    assert code == 0, err
    assert json.loads(out)["sizes_match"] is True


async def test_scan_beside_another_process_holding_2222(
    target: Target, robot_host: str, plc_host: str
) -> None:
    """Without ``--local-host`` the scan binds the address that routes to the target (here
    127.0.0.1), not 0.0.0.0: it works while another process holds UDP 2222 on another loopback
    address (and the emulator holds it on the robot's)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        try:
            probe.bind(("127.0.0.1", 2222))
        except OSError:
            pytest.skip("127.0.0.1:2222 is held by something else on this machine right now")
    holder = await asyncio.create_subprocess_exec(
        sys.executable,
        "-c",
        "import socket, sys, time\n"
        "s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)\n"
        f"s.bind(({plc_host!r}, 2222))\n"
        "print('held', flush=True)\n"
        "time.sleep(120)\n",
        stdout=asyncio.subprocess.PIPE,
    )
    try:
        assert holder.stdout is not None
        assert await asyncio.wait_for(holder.stdout.readline(), 30) == b"held\n"
        code, out, err = await _run_cli(
            "scan", robot_host, "--port", str(target.tcp_port), "--seconds", "1"
        )
    finally:
        holder.kill()
        await holder.wait()
    assert code == 0, err
    summary = json.loads(out.splitlines()[-1])["summary"]
    assert summary["state"] == "connected" and summary["frames"] > 10
    assert "cannot bind" not in err
