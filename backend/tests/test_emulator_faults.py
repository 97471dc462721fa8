"""Issue 4: each fault the control API injects, seen from the scanner's side (gaps counted,
timeouts detected, refusals decoded, TCP sessions dropped) over real sockets on loopback."""

from __future__ import annotations

from collections.abc import AsyncIterator

import pytest

from cobot_hmi.scanner.originator import ConnectionState
from cobot_hmi.scanner.session import EnipSession, SessionError
from emulator_harness import DEADLINE_S, Emulator, running_emulator
from waiting import eventually

CONNECTED = ConnectionState.CONNECTED


@pytest.fixture
async def emulator(robot_host: str, plc_host: str) -> AsyncIterator[Emulator]:
    async with running_emulator(robot_host, plc_host) as emulator:
        yield emulator


async def connected(emulator: Emulator, **overrides: object) -> None:
    originator = await emulator.connect(**overrides)
    assert await originator.wait_connected(DEADLINE_S)


def lost_reasons(emulator: Emulator) -> list[str]:
    return [r or "" for s, r in emulator.connection_states if s is ConnectionState.LOST]


async def test_dropped_t2o_packets_are_counted_as_gaps(emulator: Emulator) -> None:
    await connected(emulator)
    originator = emulator.originator
    assert originator is not None
    assert originator.gaps == 0
    answer = await emulator.post("/faults", {"t2o_drop_percent": 50})
    assert answer["faults"]["t2o_drop_percent"] == 50.0  # type: ignore[index]
    await eventually(lambda: originator.gaps >= 10)
    assert originator.state is CONNECTED, "dropping half the packets keeps the connection"
    await emulator.post("/faults/clear")
    frames = originator.frames
    await eventually(lambda: originator.frames >= frames + 2)
    gaps = originator.gaps  # the last drops may land just before the clear
    await eventually(lambda: originator.frames >= frames + 30)
    assert originator.gaps == gaps
    status = (await emulator.api.get("/status")).json()
    assert status["target_counters"]["t2o_dropped"] >= 10


async def test_delayed_t2o_is_late_and_a_long_delay_times_out(emulator: Emulator) -> None:
    await connected(emulator)
    originator = emulator.originator
    assert originator is not None
    late = originator.late
    await emulator.post("/faults", {"t2o_delay_ms": 40})  # RPI 10 ms: one 40 ms hole, then late
    await eventually(lambda: originator.late > late)
    assert originator.state is CONNECTED
    # Longer than the scanner's watchdog (RPI 10 ms × 16 = 160 ms): the connection times out.
    await emulator.post("/faults", {"t2o_delay_ms": 1000})
    await eventually(lambda: any("timed out" in r for r in lost_reasons(emulator)))
    await emulator.post("/faults/clear")
    await eventually(lambda: originator.state is CONNECTED)


async def test_silent_target_is_detected_by_the_watchdog(emulator: Emulator) -> None:
    await connected(emulator)
    originator = emulator.originator
    assert originator is not None
    await emulator.post("/faults", {"t2o_silent": True})
    await eventually(lambda: any("timed out" in r for r in lost_reasons(emulator)))
    assert originator.state is not CONNECTED
    await emulator.post("/faults/clear")
    await eventually(lambda: originator.state is CONNECTED)


async def test_corrupted_t2o_packets_are_counted_as_malformed_then_gaps(
    emulator: Emulator,
) -> None:
    # RPI × 512 (5.12 s) before the scanner gives up: not a watchdog test, and a reconnect
    # (as a busy machine brought about at RPI × 16) starts the counts of a new connection.
    await connected(emulator, timeout_multiplier=7)
    originator = emulator.originator
    assert originator is not None
    assert originator.malformed == 0
    await emulator.post("/faults", {"t2o_corrupt_count": 5})
    await eventually(lambda: originator.malformed == 5)
    await eventually(lambda: originator.gaps >= 5)  # their sequence numbers were used up
    assert originator.state is CONNECTED
    status = (await emulator.api.get("/status")).json()
    assert status["faults"]["t2o_corrupt_count"] == 0
    assert status["target_counters"]["t2o_corrupted"] == 5


async def test_refused_forward_open_is_decoded(emulator: Emulator) -> None:
    await emulator.post("/faults", {"refuse_next_forward_open": "0x0113"})
    originator = await emulator.connect()
    await eventually(
        lambda: any(s is ConnectionState.REFUSED for s, _ in emulator.connection_states)
    )
    reason = next(r for s, r in emulator.connection_states if s is ConnectionState.REFUSED)
    assert reason is not None
    assert "0x0113" in reason
    assert "out of connections" in reason
    # One refusal only: the scanner's next attempt connects.
    assert await originator.wait_connected(DEADLINE_S)
    status = (await emulator.api.get("/status")).json()
    assert status["faults"]["refuse_next_forward_open"] is None


async def test_dropping_tcp_sessions_closes_them_and_class_1_carries_on(
    emulator: Emulator, plc_host: str
) -> None:
    await connected(emulator)
    originator = emulator.originator
    assert originator is not None
    session = EnipSession(
        emulator.target.settings.host, emulator.target.tcp_port, 5.0, local_host=plc_host
    )
    await session.open()
    try:
        identity = await session.list_identity()
        assert identity.product_code == emulator.target.identity.product_code
        answer = await emulator.post("/faults", {"drop_sessions": True})
        assert answer["sessions_dropped"] is True
        with pytest.raises(SessionError):
            await session.list_identity()
    finally:
        await session.close()
    packets = originator.packets_in
    await eventually(lambda: originator.packets_in > packets + 10)
    assert originator.state is CONNECTED
