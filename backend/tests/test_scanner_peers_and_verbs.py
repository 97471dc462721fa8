"""pycomm3 (an independent peer from PyPI) against our emulator, and the ``probe``, ``scan`` and
``emulator`` verbs as a user runs them."""

from __future__ import annotations

import asyncio
import json
import signal
import sys
from collections.abc import AsyncIterator

import pytest

from cobot_hmi.emulator.static_robot import StaticRobot
from cobot_hmi.emulator.target import Target
from cobot_hmi.emulator.target_settings import TargetSettings
from cobot_hmi.scanner import explicit
from conftest import free_tcp_port


@pytest.fixture
async def target(robot_host: str) -> AsyncIterator[Target]:
    emulator = Target(TargetSettings(host=robot_host, tcp_port=0), StaticRobot())
    await emulator.start()
    try:
        yield emulator
    finally:
        await emulator.stop()


async def test_pycomm3_reads_identity_and_assembly_100(target: Target, robot_host: str) -> None:
    result = await asyncio.to_thread(explicit.probe, robot_host, target.tcp_port)
    assert result.identity["product_name"] == target.identity.product_name
    assert result.identity["product_code"] == target.identity.product_code
    assert (result.o2t_size, result.t2o_size) == (20, 284)
    assert result.frame is not None
    assert result.frame.robot_state == 13  # STANDALONE_STANDBY


async def _run_cli(*args: str, timeout_s: float = 30.0) -> tuple[int, str, str]:
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


async def test_probe_verb(target: Target, robot_host: str) -> None:
    code, out, err = await _run_cli("probe", robot_host, "--port", str(target.tcp_port))
    assert code == 0, err
    result = json.loads(out)
    assert result["assembly_sizes"] == {"150": 20, "100": 284}
    assert result["t2o_frame"]["robot_state_name"] == "STANDALONE_STANDBY"


async def test_scan_verb_frames_stats_and_refusal(
    target: Target, robot_host: str, plc_host: str
) -> None:
    common = (robot_host, "--port", str(target.tcp_port), "--local-host", plc_host)
    code, out, err = await _run_cli("scan", *common, "--seconds", "1", "--rpi-ms", "5")
    assert code == 0, err
    lines = [json.loads(line) for line in out.splitlines()]
    frames = [line for line in lines if "frame" in line]
    assert len(frames) > 10
    assert [f["seq"] for f in frames] == list(range(1, len(frames) + 1))
    assert lines[-1]["summary"]["state"] == "connected"
    assert lines[-1]["summary"]["gaps"] == 0

    code, out, err = await _run_cli("scan", *common, "--seconds", "1.5", "--stats", "--input-only")
    assert code == 0, err
    assert any(json.loads(line).get("state") == "connected" for line in out.splitlines()[:-1])

    # Seconds enough for the refusal to come on a busy machine (at load 30 half a second ran out
    # with the Forward Open unanswered: exit 3, no connection, not 2, refused).
    code, out, err = await _run_cli("scan", *common, "--seconds", "5", "--sizes", "20,280")
    assert code == 2, out
    summary = json.loads(out.splitlines()[-1])["summary"]
    assert "invalid T→O connection size (0x0128)" in summary["reason"]
    assert "expected 286 bytes" in summary["reason"]


async def test_emulator_verb_serves_until_sigterm(robot_host: str) -> None:
    port = free_tcp_port(robot_host)
    process = await asyncio.create_subprocess_exec(
        sys.executable,
        "-m",
        "cobot_hmi.cli",
        "emulator",
        "--host",
        robot_host,
        "--tcp-port",
        str(port),
        stdout=asyncio.subprocess.PIPE,
        stderr=asyncio.subprocess.PIPE,
    )
    try:
        assert process.stdout is not None
        banner = await asyncio.wait_for(process.stdout.readline(), 20)
        assert b"EtherNet/IP target" in banner
        identity = await asyncio.to_thread(explicit.list_identity, robot_host, port)
        assert identity["product_code"] == 1013
    finally:
        if process.returncode is None:
            process.send_signal(signal.SIGTERM)
        code = await asyncio.wait_for(process.wait(), 20)
        await process.communicate()
    assert code == 0
