"""Our scanner ↔ our emulator over real sockets on loopback (issue 3, "Tests"): data both ways,
idle vs run, Forward Close, watchdog expiry on both sides, every refusal with its status.

The emulator is a robot on ``robot_host`` (TCP on a free port, UDP 2222); each scanner is a PLC
on its own ``plc_host`` address, UDP 2222.
"""

from __future__ import annotations

import asyncio
import dataclasses
import random
import socket
from collections.abc import AsyncIterator, Awaitable, Callable

import pytest

from cobot_hmi.codec import CommandImage, Frame, command_from_json, encode_command
from cobot_hmi.emulator.process_image import IdleBehaviour
from cobot_hmi.emulator.static_robot import StaticRobot
from cobot_hmi.emulator.target import Target
from cobot_hmi.enip import epath, io
from cobot_hmi.enip.cip import MessageRouterRequest, Service
from cobot_hmi.enip.connection_manager import (
    ConnectionType,
    ForwardOpenRequest,
    NetworkParams,
    decode_forward_open_reply,
)
from cobot_hmi.enip.identity import decode_attributes_all
from cobot_hmi.enip.status import ExtendedStatus, GeneralStatus
from cobot_hmi.scanner.originator import (
    ConnectionState,
    NotConnectedError,
    Originator,
    OriginatorSettings,
    ReadOnlyError,
)
from cobot_hmi.scanner.session import EnipSession
from conftest import _next_host as next_host
from waiting import WAIT_DEADLINE_S, eventually

pytestmark = pytest.mark.both_pumps  # conftest: native and pure-Python pump
DEADLINE_S = WAIT_DEADLINE_S


Factory = Callable[..., Awaitable[Originator]]


@pytest.fixture
async def scanner(target: Target, robot_host: str) -> AsyncIterator[Factory]:
    """Start originators (each on a fresh PLC address unless told); all stopped at the end."""
    started: list[Originator] = []

    async def start(
        on_frame: Callable[[Frame, bytes, float, int], None] | None = None,
        on_state: Callable[[ConnectionState, str | None], None] | None = None,
        **overrides: object,
    ) -> Originator:
        options: dict[str, object] = {
            "robot_host": robot_host,
            "tcp_port": target.tcp_port,
            "local_host": next_host(),
            "rpi_us": 5_000,
        }
        options.update(overrides)
        settings = OriginatorSettings(**options)  # type: ignore[arg-type]
        originator = Originator(settings, on_frame=on_frame, on_state=on_state)
        started.append(originator)
        await originator.start()
        return originator

    try:
        yield start
    finally:
        for originator in started:
            await originator.stop()


def forward_open(**overrides: object) -> ForwardOpenRequest:
    request = ForwardOpenRequest(
        o2t_connection_id=0,
        t2o_connection_id=random.getrandbits(32) or 1,
        connection_serial=random.getrandbits(16),
        vendor_id=0x1234,
        originator_serial=random.getrandbits(32),
        timeout_multiplier=0,
        o2t_rpi_us=10_000,
        o2t_params=NetworkParams(26),
        t2o_rpi_us=10_000,
        t2o_params=NetworkParams(286),
        path=epath.connection_path(151, 150, 100),
    )
    return dataclasses.replace(request, **overrides)  # type: ignore[arg-type]


async def open_session(target: Target, robot_host: str, local_host: str) -> EnipSession:
    session = EnipSession(robot_host, target.tcp_port, 2.0, local_host)
    await session.open()
    return session


# --------------------------------------------------------------------------- data both ways


async def test_data_both_ways_idle_then_run(
    scanner: Factory, robot: StaticRobot, target: Target
) -> None:
    frames: list[int] = []
    originator = await scanner(on_frame=lambda frame, payload, at, seq: frames.append(seq))
    assert await originator.wait_connected(DEADLINE_S)
    assert originator.latest is not None
    assert (
        originator.latest[0].robot_state_name if False else originator.latest[0].robot_state == 13
    )
    assert originator.run is False

    image = command_from_json(
        {"controlbox_do": {"2": True}, "analog_output": {"0": 7.5}}, base=originator.command
    )
    sent = originator.set_command(image)
    assert await originator.wait_sent(sent, DEADLINE_S)
    await asyncio.sleep(0.05)
    assert robot.command_image().controlbox_do[2] is False, "idle: the target must not apply"

    originator.set_run(True)
    await eventually(lambda: robot.command_image() == image)
    await eventually(
        lambda: originator.latest is not None and originator.latest[0].controlbox_do[2] is True
    )
    assert originator.latest is not None
    assert originator.latest[0].analog_output[0] == pytest.approx(7.5)
    assert target.connections()[0].run is True

    originator.set_run(False)  # run → idle: the CLEAR robot drops its outputs
    await eventually(lambda: robot.command_image().controlbox_do[2] is False)
    stats = originator.stats()
    assert stats.state is ConnectionState.CONNECTED
    assert stats.packets_in > 0 and stats.packets_out > 0 and stats.malformed == 0
    assert frames == list(range(1, len(frames) + 1))


async def test_bumpless_takeover_seeds_from_actual_outputs(
    scanner: Factory, robot: StaticRobot
) -> None:
    before = command_from_json(
        {
            "controlbox_do": {"0": True, "15": True},
            "tool_do": {"5": True},
            "analog_output_type": [1, 0],
            "analog_output": [2.5, 12.0],
            "bit_input_registers": {"40": True, "3": True},
        }
    )
    robot.consume_command(before, 0.0)
    consumed = robot.commands_consumed
    originator = await scanner()
    assert await originator.wait_connected(DEADLINE_S)
    assert originator.command == before  # outputs from the frame, registers read explicitly
    originator.set_run(True)
    await eventually(lambda: robot.commands_consumed > consumed)
    assert robot.command_image() == before  # switching to run changed nothing


async def test_forward_close_frees_the_connection(scanner: Factory, target: Target) -> None:
    first = await scanner()
    assert await first.wait_connected(DEADLINE_S)
    assert [c.kind for c in target.connections()] == ["owner"]
    await first.stop()
    assert target.connections() == []
    assert target.counters.forward_closes == 1
    second = await scanner()
    assert await second.wait_connected(DEADLINE_S)


async def test_large_forward_open_and_t2o_port_request(scanner: Factory, target: Target) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    originator = await scanner(large_forward_open=True, request_t2o_port=port)
    assert await originator.wait_connected(DEADLINE_S)
    assert target.connections()[0].peer.endswith(f":{port}")


async def test_owner_and_four_input_only_or_listen_only(scanner: Factory, target: Target) -> None:
    owner = await scanner()
    assert await owner.wait_connected(DEADLINE_S)
    readers = [await scanner(input_only=True, heartbeat_o2t_size=size) for size in (0, 2, 6)]
    readers.append(await scanner(input_only=True, heartbeat_instance=199))
    for reader in readers:
        assert await reader.wait_connected(DEADLINE_S)
    kinds = sorted(c.kind for c in target.connections())
    assert kinds == ["input-only"] * 3 + ["listen-only", "owner"]
    counts = [r.stats().packets_in for r in readers]
    await eventually(
        lambda: all(r.stats().packets_in > n for r, n in zip(readers, counts, strict=True))
    )
    with pytest.raises(ReadOnlyError):
        readers[0].set_run(True)


async def test_set_run_needs_a_connection(target: Target, robot_host: str) -> None:
    originator = Originator(OriginatorSettings(robot_host=robot_host, tcp_port=target.tcp_port))
    with pytest.raises(NotConnectedError):
        originator.set_run(True)


# --------------------------------------------------------------------------- watchdogs


class CommandLog(StaticRobot):
    """The standing robot of conftest that also keeps every command image it consumed: an
    image the watchdog clears again moments later is seen whatever the polling's luck."""

    def __init__(self) -> None:
        super().__init__(IdleBehaviour.CLEAR)
        self.consumed: list[CommandImage] = []

    def consume_command(self, image: CommandImage, now_s: float) -> None:
        self.consumed.append(image)
        super().consume_command(image, now_s)


@pytest.fixture
def robot() -> CommandLog:
    return CommandLog()


async def test_target_watchdog_closes_and_applies_idle(
    target: Target, robot: CommandLog, robot_host: str, plc_host: str
) -> None:
    session = await open_session(target, robot_host, plc_host)
    try:
        response, _ = await session.request(forward_open(o2t_rpi_us=5_000).request())
        assert response.ok, response.describe()
        reply = decode_forward_open_reply(response.data)
        image = command_from_json({"controlbox_do": {"1": True}})
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as udp:
            udp.bind((plc_host, 0))
            for seq in range(1, 4):
                packet = io.encode_io(reply.o2t_connection_id, seq, seq, encode_command(image), 1)
                udp.sendto(packet, (robot_host, target.udp_port))
            # Applied (on a busy machine perhaps only at the tick that also finds the
            # connection silent and clears it again).
            await eventually(lambda: image in robot.consumed)
        # Silence: RPI 5 ms × 4 → the connection closes, the CLEAR robot drops its outputs.
        await eventually(lambda: target.connections() == [])
        assert target.counters.watchdog_timeouts == 1
        assert robot.command_image().controlbox_do[1] is False
    finally:
        await session.close()


async def test_originator_watchdog_then_reconnects(scanner: Factory, target: Target) -> None:
    states: list[ConnectionState] = []
    originator = await scanner(on_state=lambda state, reason: states.append(state))
    assert await originator.wait_connected(DEADLINE_S)
    target.faults.t2o_silent = True
    await eventually(lambda: originator.state is not ConnectionState.CONNECTED)
    assert ConnectionState.LOST in states
    lost_reason = originator.reason
    assert lost_reason is not None
    assert "timed out" in lost_reason or "no T→O" in lost_reason
    target.faults.t2o_silent = False
    assert await originator.wait_connected(DEADLINE_S)
    assert len(target.connections()) == 1


async def test_originator_counts_gaps_and_malformed(scanner: Factory, target: Target) -> None:
    # 30 % loss never silences 16 RPIs in a row, but a busy machine stalling either side can:
    # a timeout of RPI 2 ms × 512 (1 s) keeps the connection up through it.
    originator = await scanner(rpi_us=2_000, timeout_multiplier=7)
    assert await originator.wait_connected(DEADLINE_S)
    target.faults.t2o_drop_percent = 30.0
    await eventually(lambda: originator.stats().gaps >= 5)
    target.faults.t2o_drop_percent = 0.0
    target.faults.t2o_corrupt_count = 5
    await eventually(lambda: originator.stats().malformed >= 5)
    assert originator.state is ConnectionState.CONNECTED


async def test_t2o_runs_on_unbroken_between_the_pumps_stream_and_packet_by_packet(
    scanner: Factory, target: Target, robot: StaticRobot
) -> None:
    """T→O leaves as a periodic stream of the pump while the robot's data holds still between
    wake-ups; a per-packet fault (here a delay) switches to packets built one by one, clearing
    it switches back. Across both switches the sequence numbers run on: no gap, no repeat, no
    packet out of order, and the connection's count matches what arrived."""
    # A timeout of RPI 2 ms × 512 (1 s): a busy machine stalling either side for tens of ms
    # must not time the connection out (a new connection would leave `conn` closed, never to
    # stream again: a fresh clone's run at load 25 did).
    originator = await scanner(rpi_us=2_000, timeout_multiplier=7)
    assert await originator.wait_connected(DEADLINE_S)
    (conn,) = target._by_o2t.values()
    await eventually(lambda: conn.t2o_streaming)

    def arrived() -> int:
        return originator.stats().packets_in

    for _ in range(2):

        def fifty_more(wanted: int = arrived() + 50) -> bool:
            return arrived() >= wanted

        target.faults.t2o_delay_ms = 0.5
        await eventually(lambda: not conn.t2o_streaming)
        await eventually(fifty_more)
        target.faults.t2o_delay_ms = 0.0
        await eventually(lambda: conn.t2o_streaming)
        # A change to the robot's data goes into the stream.
        image = command_from_json({"tool_do": {"0": True}}, base=robot.command_image())
        robot.consume_command(image, 0.0)
        target.process_image_changed()
        await eventually(lambda: originator.latest is not None and originator.latest[0].tool_do[0])
        robot.consume_command(command_from_json({"tool_do": {"0": False}}, base=image), 0.0)
        target.process_image_changed()
        await eventually(
            lambda: originator.latest is not None and not originator.latest[0].tool_do[0]
        )
    stats = originator.stats()
    assert (stats.gaps, stats.duplicates, stats.stale, stats.malformed) == (0, 0, 0, 0)
    (info,) = target.connections()
    assert info.packets_out >= stats.packets_in > 100


async def test_a_silence_that_comes_on_between_wake_ups_holds_back_a_change(
    scanner: Factory, target: Target, robot: StaticRobot
) -> None:
    """A silence set while T→O is the pump's periodic stream, then a change to the robot's
    data before the engine's next wake-up (a write arriving at once): the change never goes
    out. The stream stops at the change; fed the change instead, it sent it until that
    wake-up, and a write a test expected to time out was confirmed."""
    shown: list[bool] = []
    originator = await scanner(
        on_frame=lambda frame, _payload, _at, _seq: shown.append(frame.tool_do[0]),
        rpi_us=2_000,
        timeout_multiplier=7,
    )
    assert await originator.wait_connected(DEADLINE_S)
    (conn,) = target._by_o2t.values()
    await eventually(lambda: conn.t2o_streaming)
    # One turn of the loop: no wake-up of the engine in between.
    target.faults.t2o_silent = True
    robot.consume_command(
        command_from_json({"tool_do": {"0": True}}, base=robot.command_image()), 0.0
    )
    target.process_image_changed()
    await eventually(lambda: originator.state is not ConnectionState.CONNECTED)
    assert shown
    assert not any(shown), "the change went out after the silence began"


# --------------------------------------------------------------------------- refusals

REFUSALS = [
    ("wrong O→T size", {"o2t_params": NetworkParams(22)}, (0x0127, 26)),
    ("wrong T→O size", {"t2o_params": NetworkParams(284)}, (0x0128, 286)),
    ("unknown connection point", {"path": epath.connection_path(151, 150, 101)}, (0x0117,)),
    ("bad path segment", {"path": bytes.fromhex("2004e0002c962c64")}, (0x0315,)),
    ("RPI too short", {"o2t_rpi_us": 500}, (0x0111,)),
    ("RPI too long", {"t2o_rpi_us": 20_000_000}, (0x0111,)),
    (
        "listen-only alone",
        {"path": epath.connection_path(151, 199, 100), "o2t_params": NetworkParams(0)},
        (0x0119,),
    ),
    ("multicast T→O", {"t2o_params": NetworkParams(286, ConnectionType.MULTICAST)}, (0x0124,)),
]


@pytest.mark.parametrize(("case", "overrides", "expected"), REFUSALS, ids=[r[0] for r in REFUSALS])
async def test_forward_open_refusals(  # noqa: PLR0917
    target: Target,
    robot_host: str,
    plc_host: str,
    case: str,
    overrides: dict[str, object],
    expected: tuple[int, ...],
) -> None:
    session = await open_session(target, robot_host, plc_host)
    try:
        response, _ = await session.request(forward_open(**overrides).request())
        assert response.general_status == GeneralStatus.CONNECTION_FAILURE
        assert response.additional_status == expected, response.describe()
        assert target.connections() == []
    finally:
        await session.close()


async def test_second_owner_and_duplicate_forward_open(
    target: Target, robot_host: str, plc_host: str
) -> None:
    session = await open_session(target, robot_host, plc_host)
    try:
        first = forward_open(timeout_multiplier=7)
        ok, _ = await session.request(first.request())
        assert ok.ok
        duplicate, _ = await session.request(first.request())
        assert duplicate.additional_status == (ExtendedStatus.CONNECTION_IN_USE,)
        second, _ = await session.request(forward_open().request())
        assert second.additional_status == (ExtendedStatus.OWNERSHIP_CONFLICT,)
        assert "ownership conflict" in second.describe()
    finally:
        await session.close()


async def test_refusal_reaches_the_originator_in_words(scanner: Factory, target: Target) -> None:
    originator = await scanner(o2t_size=18)
    await eventually(lambda: originator.state is ConnectionState.REFUSED)
    assert originator.reason is not None
    assert "invalid O→T connection size (0x0127)" in originator.reason
    assert "expected 26 bytes" in originator.reason
    target.faults.refuse_next_forward_open = 0x0113
    other = await scanner()
    await eventually(lambda: other.state is ConnectionState.REFUSED)
    assert other.reason is not None and "out of connections" in other.reason
    assert await other.wait_connected(DEADLINE_S)  # it keeps retrying with backoff


# --------------------------------------------------------------------------- explicit side


async def test_explicit_services(
    target: Target, robot: StaticRobot, robot_host: str, plc_host: str
) -> None:
    session = await open_session(target, robot_host, plc_host)
    try:
        identity = await session.list_identity()
        assert identity.product_name == target.identity.product_name
        name = await session.get_attribute_single(1, 1, 7)
        assert name.data == target.identity.encode_attribute(7)
        everything, _ = await session.request(
            MessageRouterRequest(Service.GET_ATTRIBUTES_ALL, epath.request_path(1, 1))
        )
        assert decode_attributes_all(everything.data) == target.identity
        missing = await session.get_attribute_single(1, 1, 99)
        assert missing.general_status == GeneralStatus.ATTRIBUTE_NOT_SUPPORTED
        size = await session.get_attribute_single(4, 100, 4)
        assert size.data == (284).to_bytes(2, "little")
        image = command_from_json({"bit_input_registers": {"63": True}})
        write = MessageRouterRequest(
            Service.SET_ATTRIBUTE_SINGLE, epath.request_path(4, 150, 3), encode_command(image)
        )
        response, _ = await session.request(write)
        assert response.ok, response.describe()
        assert robot.command_image() == image
        short = dataclasses.replace(write, data=b"\x00" * 19)
        assert (await session.request(short))[0].general_status == GeneralStatus.NOT_ENOUGH_DATA
        unknown_service = MessageRouterRequest(0x4B, epath.request_path(1, 1))
        reply, _ = await session.request(unknown_service)
        assert reply.general_status == GeneralStatus.SERVICE_NOT_SUPPORTED
        unknown_object = MessageRouterRequest(0x0E, epath.request_path(0x77, 1, 1))
        reply, _ = await session.request(unknown_object)
        assert reply.general_status == GeneralStatus.PATH_DESTINATION_UNKNOWN
        owned, _ = await session.request(forward_open().request())
        assert owned.ok
        reply, _ = await session.request(write)
        assert reply.general_status == GeneralStatus.OBJECT_STATE_CONFLICT
    finally:
        await session.close()
