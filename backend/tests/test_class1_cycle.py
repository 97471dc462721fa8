"""The class 1 cycle's machinery (one wake-up per cycle where possible), functionally: the O→T
schedule (sent with T→O arrivals when due, its own timer otherwise, never stopping), the target
reading O→T at its ticks or as it arrives depending on the RPI, packets read late keeping their
arrival time, and both watchdogs surviving a stall of the event loop itself. Deadlines are
generous: nothing here asserts a timing figure.
"""

from __future__ import annotations

import asyncio
import socket
import time
from collections.abc import Callable

import pytest

from cobot_hmi.codec import command_from_json
from cobot_hmi.emulator.static_robot import StaticRobot
from cobot_hmi.emulator.target import TICK_READ_MAX_RPI_US, Target
from cobot_hmi.scanner.o2t_schedule import O2TSchedule
from cobot_hmi.scanner.originator import ConnectionState, Originator, OriginatorSettings
from cobot_hmi.udp_endpoint import UdpEndpoint

DEADLINE_S = 5.0


async def eventually(check: Callable[[], bool], timeout_s: float = DEADLINE_S) -> None:
    loop = asyncio.get_running_loop()
    end = loop.time() + timeout_s
    while not check():
        assert loop.time() < end, "condition not reached in time"
        await asyncio.sleep(0.01)


# --------------------------------------------------------------------------- O→T schedule


async def test_schedule_sends_at_once_then_every_slot_without_t2o() -> None:
    sent: list[float] = []
    loop = asyncio.get_running_loop()
    schedule = O2TSchedule(0.01, lambda: sent.append(loop.time()), follow_t2o=True)
    schedule.start()
    try:
        assert len(sent) == 1, "the first packet leaves at once"
        await eventually(lambda: len(sent) >= 11)
        assert schedule.sent_by_timer == len(sent)
        assert schedule.sent_with_t2o == 0
    finally:
        schedule.stop()
    count = len(sent)
    await asyncio.sleep(0.05)
    assert len(sent) == count, "stopped: nothing more"


async def test_schedule_rides_on_t2o_arrivals_and_falls_back_when_they_stop() -> None:
    """T→O at the same RPI carries O→T (one wake-up per cycle); when T→O stops, the timer goes
    on alone; each slot sends one packet whichever way, so the rate stays the RPI's."""
    period_s = 0.01
    loop = asyncio.get_running_loop()
    sent: list[float] = []
    schedule = O2TSchedule(period_s, lambda: sent.append(loop.time()), follow_t2o=True)
    arrivals = 0
    handle: asyncio.TimerHandle | None = None
    first_s = loop.time() + period_s * 0.3

    def t2o() -> None:  # a producer's drift-free schedule, as the target keeps
        nonlocal arrivals, handle
        arrivals += 1
        schedule.t2o_arrived(loop.time())
        if arrivals < 60:
            handle = loop.call_at(first_s + arrivals * period_s, t2o)

    schedule.start()
    handle = loop.call_at(first_s, t2o)
    try:
        await eventually(lambda: arrivals >= 60)
        assert schedule.sent_with_t2o >= 10, "slots went out with T→O arrivals"
        start_s, count = loop.time(), len(sent)
        # Slots stay one packet each: no burst with the arrivals, none skipped.
        assert count <= arrivals + 5
        with_t2o = schedule.sent_with_t2o
        await eventually(lambda: len(sent) >= count + 10)  # T→O stopped: the timer carries on
        assert schedule.sent_with_t2o == with_t2o
        assert loop.time() - start_s >= 9 * period_s * 0.9
    finally:
        if handle is not None:
            handle.cancel()
        schedule.stop()


async def test_schedule_ignores_t2o_when_the_rpis_differ() -> None:
    loop = asyncio.get_running_loop()
    sent: list[float] = []
    schedule = O2TSchedule(0.01, lambda: sent.append(loop.time()), follow_t2o=False)
    schedule.start()
    try:
        for _ in range(20):
            schedule.t2o_arrived(loop.time())
            await asyncio.sleep(0.003)
        assert schedule.sent_with_t2o == 0
        assert len(sent) >= 3
    finally:
        schedule.stop()


# --------------------------------------------------------------------------- target and scanner


async def held(
    target: Target, robot_host: str, plc_host: str, rpi_us: int, **changes: object
) -> Originator:
    settings = OriginatorSettings(
        robot_host=robot_host, tcp_port=target.tcp_port, local_host=plc_host, rpi_us=rpi_us
    )
    originator = Originator(settings, **changes)  # type: ignore[arg-type]
    await originator.start()
    assert await originator.wait_connected(DEADLINE_S)
    return originator


@pytest.mark.parametrize(
    "rpi_us", [2_000, TICK_READ_MAX_RPI_US + 10_000], ids=["read-at-ticks", "read-on-arrival"]
)
async def test_commands_reach_the_robot_whichever_way_o2t_is_read(
    target: Target, robot: StaticRobot, robot_host: str, plc_host: str, rpi_us: int
) -> None:
    originator = await held(target, robot_host, plc_host, rpi_us)
    try:
        image = command_from_json({"controlbox_do": {"3": True}}, base=originator.command)
        originator.set_command(image)
        originator.set_run(True)
        await eventually(lambda: robot.command_image() == image)
        await eventually(
            lambda: originator.latest is not None and originator.latest[0].controlbox_do[3]
        )
        # Both directions share the RPI: O→T soon goes out with the T→O arrivals.
        await eventually(lambda: originator.o2t_sends()[0] > 0)
        assert originator.state is ConnectionState.CONNECTED
        (info,) = target.connections()
        assert info.run is True
        assert info.o2t_gaps == 0
    finally:
        await originator.stop()
    await eventually(lambda: target.connections() == [])


async def test_both_watchdogs_wait_out_a_stall_of_their_own_loop(
    target: Target, robot_host: str, plc_host: str
) -> None:
    """Scanner and target share this loop; a synchronous stall far longer than both watchdogs
    (RPI 5 ms × 16 = 80 ms) silences both directions, but only because the loop itself stood
    still: once it runs again, packets flow and neither side declares a timeout."""
    states: list[ConnectionState] = []
    originator = await held(
        target, robot_host, plc_host, 5_000, on_state=lambda state, reason: states.append(state)
    )
    try:
        states.clear()
        # The whole loop stalls, on purpose (as on a busy machine or in a long collection).
        time.sleep(0.3)  # noqa: ASYNC251
        before = originator.stats().packets_in
        await eventually(lambda: originator.stats().packets_in >= before + 20)
        assert target.counters.watchdog_timeouts == 0
        assert ConnectionState.LOST not in states
        assert originator.state is ConnectionState.CONNECTED
        assert len(target.connections()) == 1
    finally:
        await originator.stop()


# --------------------------------------------------------------------------- UDP endpoint


async def test_packets_read_later_keep_the_time_they_arrived(plc_host: str) -> None:
    """Read only at a tick, two packets 20 ms apart still show 20 ms between them: the time
    handed on is the kernel's receive time (the watchdog and O→T intervals rely on it)."""
    received: list[tuple[bytes, float]] = []
    endpoint = UdpEndpoint(
        plc_host,
        0,
        lambda data, addr, arrived: received.append((data, arrived)),
        receive_size=1501,
        kernel_timestamps=True,
    )
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender:
            sender.sendto(b"first", (plc_host, endpoint.port))
            await asyncio.sleep(0.02)
            sender.sendto(b"second", (plc_host, endpoint.port))
        await asyncio.sleep(0.01)
        endpoint.drain()  # both at once, as a producer's tick reads them
    finally:
        endpoint.close()
    assert [data for data, _ in received] == [b"first", b"second"]
    assert received[1][1] - received[0][1] >= 0.015
