"""Discovery over UDP 44818 (CIP Vol 2 §2-4.2, §2-4.6) against the real emulator on loopback:
ListIdentity unicast and broadcast (Linux's ``lo`` delivers a datagram sent to 127.255.255.255
to every socket bound to that address and the port, so the emulator's broadcast socket really
receives it), the random reply delay bounded by the request's MaxResponseDelay, ListServices,
what is not answered, and ``cobot-hmi discover``'s JSON lines and exit codes."""

from __future__ import annotations

import asyncio
import json
import random
import socket
import struct
import sys
from collections.abc import AsyncIterator, Iterator

import httpx
import pytest
from hypothesis import given
from hypothesis import strategies as st

from cobot_hmi.emulator.discovery import (
    DiscoveryServer,
    ReplyDelay,
    choose_reply_delay_ms,
    reply_delay_bound_ms,
)
from cobot_hmi.emulator.target import Target
from cobot_hmi.enip import cpf, encapsulation
from cobot_hmi.enip.cpf import Sockaddr
from cobot_hmi.enip.encapsulation import Command
from cobot_hmi.scanner.discovery import discover, list_identity_request, parse_list_identity_reply
from conftest import free_tcp_port

CLI = [sys.executable, "-m", "cobot_hmi.cli"]
LOOPBACK_BROADCAST = "127.255.255.255"
DISCOVERY_PORT = 44818
"""The real port: broadcasts go to it. Each test's emulator has a loopback address of its own."""
DEADLINE_S = 30.0
"""How long a test waits for an answer that should come in milliseconds (a busy machine)."""


@pytest.fixture
async def discovery(target: Target, robot_host: str) -> AsyncIterator[DiscoveryServer]:
    server = DiscoveryServer(target, robot_host, DISCOVERY_PORT, seed=7)
    await server.start()
    try:
        yield server
    finally:
        server.stop()


def mine(server: DiscoveryServer, requester: str) -> list[ReplyDelay]:
    """The delayed replies to ``requester``'s broadcasts (other test runs' broadcasts reach
    every emulator on loopback too)."""
    return [d for d in server.recent_delays if d.peer[0] == requester]


class RawClient:
    """A UDP socket on the PLC's address that sends encapsulation messages and reads replies."""

    def __init__(self, plc_host: str) -> None:
        self.host = plc_host
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_BROADCAST, 1)
        self.sock.bind((plc_host, 0))
        self.sock.setblocking(False)

    def close(self) -> None:
        self.sock.close()

    def send(self, data: bytes, host: str, port: int = DISCOVERY_PORT) -> None:
        self.sock.sendto(data, (host, port))

    async def receive(self, from_host: str | None, timeout_s: float = DEADLINE_S) -> bytes:
        """The next datagram from ``from_host`` (others, e.g. another run's emulator answering
        the same broadcast, are skipped), or from anywhere for ``None``."""
        loop = asyncio.get_running_loop()
        end = loop.time() + timeout_s
        while True:
            data, addr = await asyncio.wait_for(
                loop.sock_recvfrom(self.sock, 2048), max(0.0, end - loop.time())
            )
            if from_host is None or addr[0] == from_host:
                return data

    async def nothing_within(self, from_host: str, seconds: float) -> bool:
        try:
            await self.receive(from_host, seconds)
        except TimeoutError:
            return True
        return False


@pytest.fixture
def raw(plc_host: str) -> Iterator[RawClient]:
    client = RawClient(plc_host)
    yield client
    client.close()


async def test_list_identity_unicast_is_answered_at_once_with_the_targets_identity(
    discovery: DiscoveryServer, target: Target, robot_host: str, plc_host: str
) -> None:
    result = await discover([robot_host], timeout_s=DEADLINE_S, local_host=plc_host)
    assert len(result.devices) == 1
    device = result.devices[0]
    assert device.address == robot_host
    assert device.identity == target.identity
    # The Identity item announces the address the request reached and the TCP port.
    assert device.announced == Sockaddr(robot_host, target.tcp_port)
    # (Other test runs' broadcasts reach every emulator on loopback: only ours are looked at.)
    assert target.counters.udp_list_identity >= 1
    assert not mine(discovery, plc_host)  # unicast: no delay


async def test_list_identity_broadcast_on_loopback_is_answered_from_the_targets_address(
    discovery: DiscoveryServer, target: Target, robot_host: str, plc_host: str
) -> None:
    assert discovery.broadcast_errors == {}
    result = await discover(
        broadcast=[LOOPBACK_BROADCAST],
        timeout_s=DEADLINE_S,
        local_host=plc_host,
        max_delay_ms=600,
        wait_for=[robot_host],
    )
    # Other emulators on this machine (other test runs) may answer too: ours must be there.
    ours = [d for d in result.devices if d.address == robot_host]
    assert len(ours) == 1
    assert ours[0].identity == target.identity
    assert ours[0].announced == Sockaddr(robot_host, target.tcp_port)
    assert [(d.bound_ms, 0 <= d.delay_ms <= 600) for d in mine(discovery, plc_host)] == [
        (600, True)
    ]


async def test_broadcast_reply_delay_is_random_and_bounded_by_each_requests_max_delay(
    discovery: DiscoveryServer, raw: RawClient, robot_host: str
) -> None:
    # MaxResponseDelay 0 → 2000 ms, 1–500 → 500 ms, above → as asked (CIP Vol 2 §2-4.2.1).
    asked = [0, 1, 100, 500, 501, 700, 700, 700, 700, 700]
    for index, max_delay_ms in enumerate(asked):
        raw.send(list_identity_request(max_delay_ms, bytes([index]) * 6), LOOPBACK_BROADCAST)
    contexts = set()
    for _ in asked:
        header = encapsulation.decode(await raw.receive(robot_host)).header
        contexts.add(header.context)
    # Every request got its own reply, echoing its context.
    assert len(contexts) == len(asked)
    delays = mine(discovery, raw.host)
    assert [d.bound_ms for d in delays] == [2000, 500, 500, 500, 501, 700, 700, 700, 700, 700]
    assert all(0 <= d.delay_ms <= d.bound_ms for d in delays)
    assert len({d.delay_ms for d in delays}) == len(delays)  # a new random value each time


@given(context=st.binary(min_size=8, max_size=8), seed=st.integers(0, 2**32))
def test_reply_delay_never_exceeds_the_bound(context: bytes, seed: int) -> None:
    requested = int.from_bytes(context[:2], "little")
    bound = reply_delay_bound_ms(context)
    assert bound == (2000 if requested == 0 else max(500, requested))
    delay = choose_reply_delay_ms(context, random.Random(seed))
    assert 0.0 <= delay <= bound


async def test_list_services_over_udp_is_the_same_reply_as_over_tcp(
    discovery: DiscoveryServer, target: Target, raw: RawClient, robot_host: str
) -> None:
    request = encapsulation.encode(Command.LIST_SERVICES, context=b"svc-test")
    raw.send(request, robot_host)
    udp_reply = await raw.receive(robot_host)
    message = encapsulation.decode(udp_reply)
    assert message.header.command == Command.LIST_SERVICES
    assert message.header.context == b"svc-test"
    [item] = cpf.decode_items(message.data)
    version, capability = struct.unpack_from("<HH", item.data)
    assert (item.type_id, version) == (0x0100, 1)
    assert capability & 0x0020 and capability & 0x0100  # CIP over TCP, class 0/1 over UDP
    assert item.data[4:].rstrip(b"\0") == b"Communications"
    assert target.counters.udp_list_services == 1
    reader, writer = await asyncio.open_connection(robot_host, target.tcp_port)
    try:
        writer.write(request)
        tcp_reply = await asyncio.wait_for(reader.readexactly(len(udp_reply)), DEADLINE_S)
    finally:
        writer.close()
        await writer.wait_closed()
    assert tcp_reply == udp_reply


async def test_other_commands_and_garbage_over_udp_get_no_reply_and_are_counted(
    discovery: DiscoveryServer, target: Target, raw: RawClient, robot_host: str
) -> None:
    raw.send(encapsulation.encode(Command.REGISTER_SESSION, b"\x01\x00\x00\x00"), robot_host)
    raw.send(encapsulation.encode(Command.SEND_RR_DATA, bytes(8)), robot_host)
    raw.send(b"\x63\x00garbage", robot_host)
    raw.send(encapsulation.encode(Command.LIST_IDENTITY, options=1), robot_host)
    # The next good request is answered, and is the first datagram back: nothing came before it.
    raw.send(list_identity_request(0, b"after!"), robot_host)
    reply = encapsulation.decode(await raw.receive(robot_host))
    assert reply.header.context == (0).to_bytes(2, "little") + b"after!"
    assert target.counters.udp_discovery_ignored == 4
    assert target.counters.udp_list_identity >= 1


async def test_a_wildcard_server_tells_broadcast_from_unicast(
    target: Target, raw: RawClient, robot_host: str
) -> None:
    # On 0.0.0.0 one socket gets both; IP_PKTINFO says which. An ephemeral port keeps it apart
    # from every other emulator on the machine.
    server = DiscoveryServer(target, "0.0.0.0", 0, seed=3)
    await server.start()
    try:
        assert server.broadcast_hosts == ()
        raw.send(list_identity_request(0, b"unicst"), robot_host, server.port)
        [(identity, announced)] = parse_list_identity_reply(
            await raw.receive(robot_host), (0).to_bytes(2, "little") + b"unicst"
        )
        assert identity == target.identity
        assert announced == Sockaddr(robot_host, target.tcp_port)  # the address it reached
        assert not server.recent_delays
        raw.send(list_identity_request(550, b"brdcst"), LOOPBACK_BROADCAST, server.port)
        context = (550).to_bytes(2, "little") + b"brdcst"
        [(identity, _announced)] = parse_list_identity_reply(await raw.receive(None), context)
        assert identity == target.identity
        assert [d.bound_ms for d in server.recent_delays] == [550]  # taken for a broadcast
    finally:
        server.stop()


async def run_cli(*args: str) -> tuple[int, list[dict[str, object]], str]:
    process = await asyncio.create_subprocess_exec(
        *CLI, *args, stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE
    )
    stdout, stderr = await asyncio.wait_for(process.communicate(), 120)
    assert process.returncode is not None
    lines = [json.loads(line) for line in stdout.decode().splitlines()]
    return process.returncode, lines, stderr.decode()


async def test_discover_cli_prints_one_json_line_per_device_and_exits_0(
    discovery: DiscoveryServer, target: Target, robot_host: str, plc_host: str
) -> None:
    code, lines, stderr = await run_cli(
        "discover", "--timeout", str(DEADLINE_S), "--local-host", plc_host, robot_host
    )
    assert code == 0, stderr
    identity = target.identity
    assert lines == [
        {
            "address": robot_host,
            "port": target.tcp_port,
            "vendor_id": identity.vendor_id,
            "device_type": identity.device_type,
            "product_code": identity.product_code,
            "revision": identity.revision,
            "serial_number": identity.serial_number,
            "serial": f"0x{identity.serial_number:08X}",
            "product_name": identity.product_name,
            "status": identity.status,
            "state": identity.state,
        }
    ]


async def test_discover_cli_broadcast_finds_the_emulator(
    discovery: DiscoveryServer, robot_host: str, plc_host: str
) -> None:
    # The reply comes within 500 ms (the least bound); the rest of the timeout is slack.
    code, lines, stderr = await run_cli(
        "discover",
        "--broadcast",
        LOOPBACK_BROADCAST,
        "--max-delay-ms",
        "500",
        "--timeout",
        "8",
        "--local-host",
        plc_host,
    )
    assert code == 0, stderr
    assert robot_host in [line["address"] for line in lines]
    assert [d.bound_ms for d in mine(discovery, plc_host)] == [500]


async def test_discover_cli_exits_1_when_nobody_answers(plc_host: str, robot_host: str) -> None:
    # Nothing listens on robot_host here (no emulator in this test).
    code, lines, stderr = await run_cli(
        "discover", "--timeout", "0.5", "--local-host", plc_host, robot_host
    )
    assert (code, lines) == (1, [])
    assert "no device answered" in stderr


async def test_the_emulator_command_serves_discovery(robot_host: str, plc_host: str) -> None:
    control_port = free_tcp_port(robot_host)
    process = await asyncio.create_subprocess_exec(
        *CLI,
        "emulator",
        "--host",
        robot_host,
        "--tcp-port",
        "0",
        "--udp-port",
        "0",
        "--control-port",
        str(control_port),
        stdout=asyncio.subprocess.PIPE,
        stderr=asyncio.subprocess.PIPE,
    )
    try:
        assert process.stdout is not None
        banner = (await asyncio.wait_for(process.stdout.readline(), 60)).decode()
        assert f"discovery UDP {DISCOVERY_PORT}" in banner, banner
        result = await discover([robot_host], timeout_s=DEADLINE_S, local_host=plc_host)
        assert [d.address for d in result.devices] == [robot_host]
        assert result.devices[0].identity.product_name.startswith("Doosan")
        async with httpx.AsyncClient(base_url=f"http://{robot_host}:{control_port}") as api:
            status = (await api.get("/status")).json()
        assert status["discovery"] == {
            "host": robot_host,
            "port": DISCOVERY_PORT,
            "broadcast_hosts": [LOOPBACK_BROADCAST],
            "broadcast_errors": {},
            "pending_replies": 0,
        }
        assert status["target_counters"]["udp_list_identity"] >= 1
    finally:
        process.terminate()
        await asyncio.wait_for(process.communicate(), 60)


async def test_random_datagrams_are_dropped_and_the_server_goes_on(
    discovery: DiscoveryServer, target: Target, raw: RawClient, robot_host: str
) -> None:
    rng = random.Random(11)
    batch, batches = 20, 15  # small batches: the socket's receive buffer never overflows
    loop = asyncio.get_running_loop()
    for done in range(1, batches + 1):
        for _ in range(batch):
            # Command byte 0xFF: never a discovery command, whatever follows.
            raw.send(b"\xff" + rng.randbytes(rng.randrange(0, 120)), robot_host)
        end = loop.time() + DEADLINE_S
        while target.counters.udp_discovery_ignored < done * batch:
            assert loop.time() < end, "the server stopped reading"
            await asyncio.sleep(0.005)
    raw.send(list_identity_request(0, b"alive!"), robot_host)
    reply = encapsulation.decode(await raw.receive(robot_host))
    assert reply.header.context.endswith(b"alive!")
    assert target.counters.udp_discovery_ignored == batch * batches
    assert target.counters.internal_errors == 0


# ----------------------------------------------------------------- an independent peer: cpppo


async def test_discover_finds_an_independent_adapter(robot_host: str, plc_host: str) -> None:
    """cpppo's EtherNet/IP server (an adapter written by others) answers our ListIdentity."""
    process = await asyncio.create_subprocess_exec(
        sys.executable,
        "-m",
        "cpppo.server.enip",
        "--no-config",
        "--no-print",
        "-A",
        "-a",
        f"{robot_host}:{DISCOVERY_PORT}",
        stdout=asyncio.subprocess.PIPE,
        stderr=asyncio.subprocess.PIPE,
    )
    try:
        assert process.stdout is not None
        while True:  # it prints its TCP then its UDP address once it listens
            line = (await asyncio.wait_for(process.stdout.readline(), 120)).decode()
            assert line, "cpppo's server stopped"
            if "UDP Server address" in line:
                break
        result = await discover([robot_host], timeout_s=DEADLINE_S, local_host=plc_host)
        [device] = result.devices
        assert device.address == robot_host
        assert device.announced.port == DISCOVERY_PORT  # (its address field: 0.0.0.0)
        assert device.identity.product_name  # cpppo's own (a Logix controller's by default)
    finally:
        process.terminate()
        await asyncio.wait_for(process.communicate(), 60)


def _cpppo_fields(output: str, section: str) -> dict[str, str]:
    """The ``'key': value`` lines of one ``List …`` reply in cpppo's client printout."""
    fields: dict[str, str] = {}
    inside = False
    for line in output.splitlines():
        if line.startswith(section):
            inside = True
        elif inside and line.startswith("}"):
            break
        elif inside and ":" in line:
            key, _, value = line.strip().rstrip(",").partition(":")
            fields[key.strip().strip("'").rsplit(".", 1)[-1]] = value.strip().strip("'")
    return fields


async def test_an_independent_client_reads_identity_and_services_over_udp(
    discovery: DiscoveryServer, target: Target, robot_host: str
) -> None:
    """cpppo's client (written by others) sends ListIdentity and ListServices over UDP."""
    process = await asyncio.create_subprocess_exec(
        sys.executable,
        "-m",
        "cpppo.server.enip.client",
        "-a",
        f"{robot_host}:{DISCOVERY_PORT}",
        "-u",
        "-i",
        "-s",
        "-p",
        "-t",
        str(DEADLINE_S),
        stdout=asyncio.subprocess.PIPE,
        stderr=asyncio.subprocess.PIPE,
    )
    stdout, stderr = await asyncio.wait_for(process.communicate(), 120)
    output = stdout.decode()
    assert process.returncode == 0, stderr.decode()
    identity = _cpppo_fields(output, "List Identity")
    services = _cpppo_fields(output, "List Services")
    expected = target.identity
    assert identity["product_name"] == expected.product_name, output
    assert int(identity["vendor_id"]) == expected.vendor_id
    assert int(identity["product_code"]) == expected.product_code
    assert int(identity["serial_number"]) == expected.serial_number
    assert (identity["sin_addr"], int(identity["sin_port"])) == (robot_host, target.tcp_port)
    assert services["service_name"] == "Communications"
    assert int(services["capability"]) == 0x0120
    assert target.counters.udp_list_identity >= 1
    assert target.counters.udp_list_services == 1
