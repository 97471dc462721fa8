"""The Sparkplug edge node's doors against a real Mosquitto: bad commands get a clear answer and
leave the node up, a broker that is not there when the service starts (the service serves,
buffers, and births when it comes), a stalled broker stalls nothing, TLS with a password on a
listener that refuses anonymous clients (a wrong password refused and counted) and with a client
certificate as the identity, and ``cobot-hmi demo --mqtt-url``."""

from __future__ import annotations

import asyncio
import os
import shutil
import signal
import subprocess
from pathlib import Path
from typing import Any

import pytest

from conftest import _next_host, free_tcp_port
from mosquitto_support import (
    Message,
    Subscriber,
    broker_config,
    encode_command,
    mosquitto,
    needs_mosquitto,
)
from process_support import cli_process, read_until
from service_support import cell_settings, emulator, eventually, running_service
from sparkplug_support import BOOLEAN, FLOAT, GROUP, NODE, Panel, cell, edge_node_of, reported

pytestmark = [needs_mosquitto, pytest.mark.timeout(300)]

SLOW_S = 60.0


def outcomes(messages: list[Message], device: str, outcome_alias: int) -> list[Any]:
    return [value for value, _ in reported(messages, device, outcome_alias)]


async def test_bad_commands_are_answered_and_the_node_stays_up(
    tmp_path: Path, plc_host: str
) -> None:
    async with cell(tmp_path, plc_host, mqtt_writes=True) as c:
        edge = edge_node_of(c.running.service)
        assert edge is not None
        aliases = c.aliases("m1013")
        dcmd = f"spBv1.0/{GROUP}/DCMD/{NODE}/m1013"
        c.subscriber.publish(dcmd, b"\x12\xff\xff\xff\xff\x0f")  # not a payload
        c.subscriber.publish(f"spBv1.0/{GROUP}/NCMD/{NODE}", b"\xff\xff")
        c.subscriber.publish(
            f"spBv1.0/{GROUP}/DCMD/{NODE}/nope", encode_command([(None, 1, BOOLEAN, True)])
        )
        await eventually(lambda: edge.bad_commands == 3, SLOW_S)
        # Not writable, and a value of the wrong type: answered, nothing applied.
        c.subscriber.publish(dcmd, encode_command([("joint_position/J 1", None, FLOAT, 1.0)]))
        outcome_alias = aliases["Write/Outcome"]
        await c.subscriber.wait_for(lambda ms: len(outcomes(ms, "m1013", outcome_alias)) == 1)
        c.subscriber.publish(dcmd, encode_command([("Control/Take", None, BOOLEAN, True)]))
        await c.subscriber.wait_for(lambda ms: len(outcomes(ms, "m1013", outcome_alias)) == 2)
        c.subscriber.publish(
            dcmd, encode_command([(None, aliases["command/controlbox_do/DO 2"], FLOAT, 1.0)])
        )
        await c.subscriber.wait_for(lambda ms: len(outcomes(ms, "m1013", outcome_alias)) == 3)
        messages = c.subscriber.snapshot()
        assert outcomes(messages, "m1013", outcome_alias) == ["invalid", "granted", "invalid"]
        reasons = [v for v, _ in reported(messages, "m1013", aliases["Write/Reason"])]
        assert "joint_position/J 1 is not a writable metric" in reasons[0]
        assert "controlbox_do" in reasons[2]
        assert not c.panels["m1013"].command_image().controlbox_do[1]
        # Still publishing, never dead.
        panel = c.panels["m1013"]
        di = list(panel.produce_frame(0).controlbox_di)
        di[9] = True
        panel.set(controlbox_di=tuple(di))
        di10 = aliases["controlbox_di/DI 10"]
        await c.subscriber.wait_for(
            lambda ms: (True, None) in [(v, None) for v, _ in reported(ms, "m1013", di10)]
        )
        assert not c.subscriber.of("NDEATH")
        text = await c.running.metrics()
        assert 'cobot_hmi_sparkplug_commands_total{outcome="malformed"} 3.0' in text


async def test_a_broker_missing_at_start(tmp_path: Path, plc_host: str) -> None:
    panel = Panel()
    robot_host = _next_host()
    async with (
        mosquitto(plc_host, tmp_path, start=False) as broker,
        emulator(robot_host, panel) as target,
    ):
        settings = cell_settings(
            [("m1013", robot_host, target.tcp_port)],
            plc_host,
            tmp_path,
            mqtt_url=broker.url,
            sparkplug_group=GROUP,
            sparkplug_node=NODE,
        )
        async with running_service(settings) as running:
            edge = edge_node_of(running.service)
            assert edge is not None
            async with running.client() as client:  # the HMI serves without its broker
                assert (await client.get("/readyz")).status_code == 200
            assert "cobot_hmi_sparkplug_broker_connected 0.0" in await running.metrics()
            await asyncio.sleep(0.5)  # born while away: the first report comes after it
            di = list(panel.produce_frame(0).controlbox_di)
            di[6] = True
            panel.set(controlbox_di=tuple(di))
            await eventually(lambda: edge.buffer.records_buffered >= 1, SLOW_S)
            await broker.start()
            async with Subscriber(broker) as subscriber:
                await subscriber.wait_for(
                    lambda ms: any(m.is_historical for x in ms for m in x.metrics), SLOW_S
                )
                births = subscriber.of("NBIRTH")
                # Either the subscriber or the node came first; bdSeq 0: no CONNECT went out
                # while the broker was missing.
                if births:
                    assert next(m.value for m in births[0].metrics if m.name == "bdSeq") == 0
            assert edge.reconnects == 0
            assert edge.replayed >= 1


def _run(*command: str, cwd: Path) -> None:
    """A setup command, before any service runs (nothing else waits on this loop yet)."""
    subprocess.run(command, cwd=cwd, check=True, capture_output=True, timeout=60)


def _openssl(*args: str, cwd: Path) -> None:
    _run("openssl", *args, cwd=cwd)


@pytest.mark.skipif(shutil.which("openssl") is None, reason="openssl makes the test's CA")
@pytest.mark.skipif(shutil.which("mosquitto_passwd") is None, reason="mosquitto_passwd")
async def test_tls_and_a_password(tmp_path: Path, plc_host: str) -> None:
    pki = tmp_path / "pki"
    pki.mkdir()
    _openssl(
        "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", "ca.key", "-out", "ca.pem",
        "-days", "2", "-subj", "/CN=test CA", cwd=pki,
    )  # fmt: skip
    _openssl(
        "req", "-newkey", "rsa:2048", "-nodes", "-keyout", "server.key", "-out", "server.csr",
        "-subj", f"/CN={plc_host}", cwd=pki,
    )  # fmt: skip
    (pki / "san.ext").write_text(f"subjectAltName=IP:{plc_host}\n")
    _openssl(
        "x509", "-req", "-in", "server.csr", "-CA", "ca.pem", "-CAkey", "ca.key",
        "-CAcreateserial", "-out", "server.pem", "-days", "2", "-extfile", "san.ext", cwd=pki,
    )  # fmt: skip
    _openssl(
        "req", "-newkey", "rsa:2048", "-nodes", "-keyout", "client.key", "-out", "client.csr",
        "-subj", "/CN=cell-7", cwd=pki,
    )  # fmt: skip
    _openssl(
        "x509", "-req", "-in", "client.csr", "-CA", "ca.pem", "-CAkey", "ca.key",
        "-CAcreateserial", "-out", "client.pem", "-days", "2", cwd=pki,
    )  # fmt: skip
    passwords = tmp_path / "passwords"
    _run("mosquitto_passwd", "-b", "-c", str(passwords), "cell-7", "s3cret-cell", cwd=tmp_path)
    os.chmod(passwords, 0o644)
    for path in pki.iterdir():
        os.chmod(path, 0o644)
    tls_port = free_tcp_port(plc_host)
    plain_port = free_tcp_port(plc_host)
    mutual_port = free_tcp_port(plc_host)
    lines = (
        "per_listener_settings true",
        f"listener {tls_port} {plc_host}",
        f"cafile {pki / 'ca.pem'}",
        f"certfile {pki / 'server.pem'}",
        f"keyfile {pki / 'server.key'}",
        "allow_anonymous false",
        f"password_file {passwords}",
        f"listener {plain_port} {plc_host}",  # the test's reader
        "allow_anonymous true",
        f"listener {mutual_port} {plc_host}",  # a client certificate is the identity
        f"cafile {pki / 'ca.pem'}",
        f"certfile {pki / 'server.pem'}",
        f"keyfile {pki / 'server.key'}",
        "require_certificate true",
        "use_identity_as_username true",
        "allow_anonymous false",
    )
    panel = Panel()
    robot_host = _next_host()
    async with (
        mosquitto(plc_host, tmp_path, port=plain_port, lines=lines) as broker,
        Subscriber(broker) as subscriber,
        emulator(robot_host, panel) as target,
    ):
        base = cell_settings(
            [("m1013", robot_host, target.tcp_port)],
            plc_host,
            tmp_path,
            mqtt_url=f"mqtts://{plc_host}:{tls_port}",
            mqtt_ca_file=pki / "ca.pem",
            mqtt_user="cell-7",
            sparkplug_group=GROUP,
            sparkplug_node=NODE,
        )
        async with running_service(base.replace(mqtt_password="wrong")) as running:
            edge = edge_node_of(running.service)
            assert edge is not None
            await eventually(lambda: edge.connect_refusals >= 1, SLOW_S)
            assert not subscriber.of("NBIRTH")
        async with running_service(base.replace(mqtt_password="s3cret-cell")):
            await subscriber.wait_for(lambda ms: any(m.kind == "DBIRTH" for m in ms), SLOW_S)
        mutual = base.replace(
            mqtt_url=f"mqtts://{plc_host}:{mutual_port}",
            mqtt_user="",
            mqtt_client_cert=pki / "client.pem",
            mqtt_client_key=pki / "client.key",
        )
        births = len(subscriber.of("NBIRTH"))
        async with running_service(mutual) as running:
            await subscriber.wait_for(lambda ms: sum(m.kind == "NBIRTH" for m in ms) > births)
            node = edge_node_of(running.service)
            assert node is not None and node.connect_refusals == 0


async def test_demo_passes_the_broker_on(robot_host: str, plc_host: str, tmp_path: Path) -> None:
    async with (
        mosquitto(plc_host, tmp_path) as broker,
        Subscriber(broker) as subscriber,
        cli_process(
            "demo",
            "--robots",
            "1",
            "--robot-host",
            robot_host,
            "--robot-tcp-port",
            str(free_tcp_port(robot_host)),
            "--control-port",
            "0",
            "--local-host",
            plc_host,
            "--host",
            plc_host,
            "--port",
            str(free_tcp_port(plc_host)),
            "--state-dir",
            str(tmp_path / "state"),
            "--mqtt-url",
            broker.url,
            interrupt_first=True,
        ) as demo,
    ):
        said = "".join(await read_until(demo, "Ctrl-C stops all", SLOW_S))
        assert f"Sparkplug B to {broker.url}: spBv1.0/cobot-hmi/+/" in said
        await subscriber.wait_for(lambda ms: any(m.kind == "DBIRTH" for m in ms), SLOW_S)
        assert subscriber.of("DBIRTH")[0].device == "m1013"


_ = broker_config  # (re-exported for tests that build a broker by hand)


async def test_a_stalled_broker_stalls_nothing(tmp_path: Path, plc_host: str) -> None:
    """Mosquitto stopped (SIGSTOP: the TCP connection stays open, nothing is read): the robots'
    connections, the frames and the HMI go on; after SIGCONT the node publishes again."""
    async with cell(tmp_path, plc_host, ramp=3.0) as c:
        process = c.broker.process
        assert process is not None
        robots = c.running.service.robots
        process.send_signal(signal.SIGSTOP)
        try:
            before = {name: robot.frames.seq for name, robot in robots.items()}
            await eventually(
                lambda: all(
                    robot.frames.seq > before[name] + 100 for name, robot in robots.items()
                ),
                SLOW_S,
            )
            async with c.running.client() as client:
                assert (await client.get("/readyz")).status_code == 200
            assert all(robot.connection.down_since is None for robot in robots.values())
        finally:
            process.send_signal(signal.SIGCONT)
        count = len(c.subscriber.of("DDATA", "m1013"))
        await c.subscriber.wait_for(lambda ms: len([m for m in ms if m.kind == "DDATA"]) > count)
        assert not c.subscriber.of("NDEATH")
