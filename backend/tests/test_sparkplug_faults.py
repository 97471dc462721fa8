"""The Sparkplug edge node through faults, against a real Mosquitto: NDEATH (the will) when the
service is killed with ``kill -9`` and bdSeq going on after a restart, DDEATH and DBIRTH around
an emulator restart (the other robot untouched), and the broker going away: the service keeps
running, buffers on disk and, after the reconnect, sends NBIRTH, DBIRTHs and the buffered data
marked historical. Deadlines are generous: the machine is shared."""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import signal
import time
from asyncio.subprocess import Process
from pathlib import Path
from typing import Any

import orjson
import pytest

from cobot_hmi.settings import HmiSettings
from conftest import _next_host, free_tcp_port
from frame_support import CollectedFrames
from mosquitto_support import Message, Subscriber, encode_command, mosquitto, needs_mosquitto
from process_support import DEVNULL, cli_process
from service_support import cell_settings, emulator, eventually, running_service
from sparkplug_support import (
    BOOLEAN,
    GROUP,
    NODE,
    Cell,
    Panel,
    cell,
    edge_node_of,
    node_messages,
    reported,
)

pytestmark = [needs_mosquitto, pytest.mark.timeout(300)]

SLOW_S = 60.0
"""Deadline for anything that waits on a watchdog, a reconnect backoff or a restart."""


def transitions(c: Cell, device: str, di_index: int) -> list[tuple[bool, int]]:
    """``(value, ms)`` of each change of one digital input in the frames the service received."""
    out = []
    previous = None
    for _, t, frame, _, _ in c.frames_seen(device):
        value = frame.controlbox_di[di_index]
        if previous is not None and value != previous:
            out.append((value, int(t * 1000)))
        previous = value
    return out


def bd_seq(message: Message) -> Any:
    return next(m.value for m in message.metrics if m.name == "bdSeq")


def serve_process(*args: str) -> contextlib.AbstractAsyncContextManager[Process]:
    return cli_process("serve", *args, stdout=DEVNULL, stderr=DEVNULL)


async def test_ndeath_on_kill_9_and_bdseq_goes_on(
    robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    async with (
        mosquitto(plc_host, tmp_path) as broker,
        Subscriber(broker) as subscriber,
        emulator(robot_host) as target,
    ):
        args = (
            "--robot",
            robot_host,
            "--robot-tcp-port",
            str(target.tcp_port),
            "--local-host",
            plc_host,
            "--host",
            plc_host,
            "--port",
            str(free_tcp_port(plc_host)),
            "--state-dir",
            str(tmp_path / "state"),
            "--timeout-multiplier",
            "5",
            "--mqtt-url",
            broker.url,
            "--sparkplug-node",
            NODE,
        )
        async with serve_process(*args) as service:
            await subscriber.wait_for(lambda ms: any(m.kind == "DBIRTH" for m in ms), SLOW_S)
            first = subscriber.of("NBIRTH")[0]
            assert not subscriber.of("NDEATH")
            service.send_signal(signal.SIGKILL)
            await service.wait()
            await subscriber.wait_for(lambda ms: any(m.kind == "NDEATH" for m in ms), SLOW_S)
        death = subscriber.of("NDEATH")[0]
        assert death.topic == f"spBv1.0/cobot-hmi/NDEATH/{NODE}"
        assert bd_seq(death) == bd_seq(first)
        assert death.seq is None
        # The next process counts on: a late will of the old one cannot end the new session.
        async with serve_process(*args):
            await subscriber.wait_for(lambda ms: len([m for m in ms if m.kind == "NBIRTH"]) == 2)
            second = subscriber.of("NBIRTH")[1]
            assert bd_seq(second) == (bd_seq(first) + 1) % 256


async def test_ddeath_and_dbirth_around_an_emulator_restart(tmp_path: Path, plc_host: str) -> None:
    async with cell(tmp_path, plc_host) as c:
        await c.stop_robot("m0609")
        await c.subscriber.wait_for(lambda ms: any(m.kind == "DDEATH" for m in ms), SLOW_S)
        await c.start_robot("m0609")
        await c.subscriber.wait_for(
            lambda ms: len([m for m in ms if m.kind == "DBIRTH" and m.device == "m0609"]) == 2,
            SLOW_S,
        )
        lifecycle = [
            m.kind for m in c.subscriber.snapshot() if m.device == "m0609" and m.kind != "DDATA"
        ]
        assert lifecycle == ["DBIRTH", "DDEATH", "DBIRTH"]
        assert not c.subscriber.of("DDEATH", "m1013")
        seqs = [m.seq for m in node_messages(c.subscriber.snapshot())]
        assert seqs == [i % 256 for i in range(len(seqs))]
        text = await c.running.metrics()
        assert 'cobot_hmi_sparkplug_messages_total{robot="m0609",type="DDEATH"} 1.0' in text


async def test_broker_restart_replays_the_buffer_as_historical(
    tmp_path: Path, plc_host: str
) -> None:
    async with cell(tmp_path, plc_host, persistent_broker=True) as c:
        edge = edge_node_of(c.running.service)
        assert edge is not None
        first_bd_seq = bd_seq(c.subscriber.of("NBIRTH")[0])
        alias = c.aliases("m1013")["controlbox_di/DI 5"]
        await c.broker.stop()
        await eventually(lambda: not edge.online, SLOW_S)
        panel = c.panels["m1013"]
        di = list(panel.produce_frame(0).controlbox_di)
        for k in range(8):  # the service keeps running: these go to the disk buffer
            di[4] = k % 2 == 0
            panel.set(controlbox_di=tuple(di))
            await asyncio.sleep(0.15)
        expected = transitions(c, "m1013", 4)
        assert len(expected) >= 4  # the frames showed the toggles
        device = edge.devices["m1013"]
        # The edge node has reported past the last change (into the buffer) before the return.
        await eventually(
            lambda: device.frame is not None and int(device.frame[1] * 1000) > expected[-1][1],
            SLOW_S,
        )
        assert edge.buffer.records_buffered >= 1
        await c.broker.start()
        await c.subscriber.wait_for(
            lambda ms: (
                len([m for m in ms if m.kind == "NBIRTH"]) == 2
                and any(metric.is_historical for m in ms for metric in m.metrics)
            ),
            SLOW_S,
        )
        await eventually(lambda: edge.buffer.records_buffered == 0, SLOW_S)

        def historical_after_rebirth(messages: list[Message]) -> list[tuple[Any, int | None]]:
            after = messages[messages.index(c.subscriber.of("NBIRTH")[1]) :]
            return [
                (metric.value, metric.timestamp)
                for m in after
                if m.kind == "DDATA" and m.device == "m1013"
                for metric in m.metrics
                if metric.alias == alias and metric.is_historical
            ]

        # Sent from the buffer is not yet received: wait until the subscriber has them all.
        await c.subscriber.wait_for(
            lambda ms: len(historical_after_rebirth(ms)) >= len(expected), SLOW_S
        )
        messages = c.subscriber.snapshot()
        assert bd_seq(c.subscriber.of("NBIRTH")[1]) == (first_bd_seq + 1) % 256
        # After the reconnect: NBIRTH, both DBIRTHs, then the history.
        after = messages[messages.index(c.subscriber.of("NBIRTH")[1]) :]
        assert [m.kind for m in after[:3]] == ["NBIRTH", "DBIRTH", "DBIRTH"]
        # Every transition of the outage, in order, as it was.
        historical = historical_after_rebirth(messages)
        assert historical == expected
        # Live data after the replay is not historical, and DI 5 reads the same as the robot.
        live = reported(c.subscriber.snapshot(), "m1013", alias)
        assert live[-1][0] == c.frames_seen("m1013")[-1][2].controlbox_di[4]
        text = await c.running.metrics()
        assert "cobot_hmi_sparkplug_reconnects_total 1.0" in text
        # Replayed counts the buffered messages sent again (a report may carry more than one
        # transition): at least every historical message received, and /metrics says it.
        replayed = [
            m
            for m in after
            if m.kind == "DDATA" and any(metric.is_historical for metric in m.metrics)
        ]
        assert edge.replayed >= len(replayed) >= 1
        assert f"cobot_hmi_sparkplug_replayed_total {float(edge.replayed)}" in text


def _state(online: bool, timestamp_ms: int) -> bytes:
    return orjson.dumps({"online": online, "timestamp": timestamp_ms})


async def test_births_wait_for_the_primary_host(tmp_path: Path, plc_host: str) -> None:
    """With a primary host application configured: no birth until its STATE says online (the
    data meanwhile buffered, then historical); its going offline brings NDEATH and a new
    connection (next bdSeq) that waits again; an older STATE changes nothing."""
    async with cell(
        tmp_path, plc_host, ramp=3.0, wait_births=False, sparkplug_primary_host="scada"
    ) as c:
        edge = edge_node_of(c.running.service)
        assert edge is not None
        state_topic = "spBv1.0/STATE/scada"
        await eventually(lambda: edge.online and edge.buffer.records_buffered >= 3, SLOW_S)
        assert not edge.active
        assert not c.subscriber.of("NBIRTH")
        first = int(time.time() * 1000)
        c.subscriber.publish(state_topic, _state(True, first), retain=True)
        await c.subscriber.wait_for(
            lambda ms: (
                sum(m.kind == "DBIRTH" for m in ms) == 2
                and any(metric.is_historical for m in ms for metric in m.metrics)
            ),
            SLOW_S,
        )
        born_bd_seq = bd_seq(c.subscriber.of("NBIRTH")[0])
        connections = edge.connections
        c.subscriber.publish(state_topic, _state(False, first + 1), retain=True)
        await c.subscriber.wait_for(lambda ms: any(m.kind == "NDEATH" for m in ms), SLOW_S)
        assert bd_seq(c.subscriber.of("NDEATH")[0]) == born_bd_seq
        await eventually(lambda: edge.connections == connections + 1, SLOW_S)
        assert not edge.active
        c.subscriber.publish(state_topic, _state(True, first + 2), retain=True)
        await c.subscriber.wait_for(lambda ms: sum(m.kind == "NBIRTH" for m in ms) == 2, SLOW_S)
        assert bd_seq(c.subscriber.of("NBIRTH")[1]) == (born_bd_seq + 1) % 256
        # A late, older "offline" is ignored: a rebirth request after it is still answered.
        c.subscriber.publish(state_topic, _state(False, first), retain=False)
        c.subscriber.publish(
            f"spBv1.0/{GROUP}/NCMD/{NODE}",
            encode_command([("Node Control/Rebirth", None, BOOLEAN, True)]),
        )
        await c.subscriber.wait_for(lambda ms: sum(m.kind == "NBIRTH" for m in ms) == 3, SLOW_S)
        assert len(c.subscriber.of("NDEATH")) == 1
        assert edge.active
        assert "cobot_hmi_sparkplug_born 1.0" in await c.running.metrics()


async def test_a_buffer_left_by_a_run_goes_out_with_the_next(tmp_path: Path, plc_host: str) -> None:
    """The broker away for a whole run: what it buffered goes out, historical, after the next
    run's births, under the aliases of that run (whose robots are listed in another order)."""
    panels = {"m1013": Panel(), "m0609": Panel()}
    hosts = {name: _next_host() for name in panels}
    async with contextlib.AsyncExitStack() as stack:
        broker = await stack.enter_async_context(mosquitto(plc_host, tmp_path, start=False))
        ports = {}
        for name, panel in panels.items():
            target = await stack.enter_async_context(emulator(hosts[name], panel))
            ports[name] = target.tcp_port

        def settings(order: list[str]) -> HmiSettings:
            return cell_settings(
                [(name, hosts[name], ports[name]) for name in order],
                plc_host,
                tmp_path,
                mqtt_url=broker.url,
                sparkplug_group=GROUP,
                sparkplug_node=NODE,
            )

        async with running_service(settings(["m1013", "m0609"])) as first:
            edge = edge_node_of(first.service)
            assert edge is not None
            frames = CollectedFrames(first.service.robots["m1013"].frames, 100_000)
            await asyncio.sleep(0.3)  # past the (unsent) birth: the toggles are reports
            di = list(panels["m1013"].produce_frame(0).controlbox_di)
            for k in range(4):
                di[4] = k % 2 == 0
                panels["m1013"].set(controlbox_di=tuple(di))
                await asyncio.sleep(0.15)
            seen = frames.seen()
            expected = []
            for (_, _, a, _, _), (_, t, b, _, _) in itertools.pairwise(seen):
                if a.controlbox_di[4] != b.controlbox_di[4]:
                    expected.append((b.controlbox_di[4], int(t * 1000)))
            assert len(expected) >= 2
            device = edge.devices["m1013"]
            await eventually(
                lambda: device.frame is not None and int(device.frame[1] * 1000) > expected[-1][1],
                SLOW_S,
            )
        await broker.start()
        async with (
            Subscriber(broker) as subscriber,
            running_service(settings(["m0609", "m1013"])),
        ):
            await subscriber.wait_for(
                lambda ms: any(metric.is_historical for m in ms for metric in m.metrics), SLOW_S
            )
            alias = next(
                m.alias
                for m in subscriber.of("DBIRTH", "m1013")[0].metrics
                if m.name == "controlbox_di/DI 5"
            )
            assert alias is not None and alias // 1000 == 2  # second in this run's settings
            await subscriber.wait_for(
                lambda ms: (
                    [
                        (metric.value, metric.timestamp)
                        for m in ms
                        if m.kind == "DDATA" and m.device == "m1013"
                        for metric in m.metrics
                        if metric.alias == alias and metric.is_historical
                    ]
                    == expected
                ),
                SLOW_S,
            )
            messages = subscriber.snapshot()
            birth = messages.index(subscriber.of("DBIRTH", "m1013")[0])
            history = [
                i
                for i, m in enumerate(messages)
                if m.device == "m1013" and any(x.is_historical for x in m.metrics)
            ]
            assert history and min(history) > birth  # its history only after its birth
