"""The service as a Sparkplug B edge node against a real Mosquitto, two emulated robots, read by
an independent subscriber (``mosquitto_support``: its own protobuf wire reader).

Births (every layout field a metric, names and units from the layout, the robot state an
integer with its name, aliases unique across the node), seq numbering, DDATA equal to the
frames the service received, bits never lost, deadbands and the maximum rate respected,
rebirth on NCMD, DCMD writes through the write pipeline, and the ``/metrics`` counters.
"""

from __future__ import annotations

import asyncio
import itertools
import sqlite3
from contextlib import closing
from pathlib import Path
from typing import Any

import pytest

from mosquitto_support import (
    Message,
    encode_command,
    needs_mosquitto,
)
from service_support import eventually
from sparkplug_support import (
    BOOLEAN,
    EXPECTED_O2T,
    EXPECTED_T2O,
    FLOAT,
    GROUP,
    INT64,
    NODE,
    UINT8,
    Cell,
    cell,
    edge_node_of,
    f32,
    node_messages,
)

pytestmark = [needs_mosquitto, pytest.mark.timeout(240)]


async def test_births_seq_and_data_equal_to_frames(tmp_path: Path, plc_host: str) -> None:
    async with cell(tmp_path, plc_host, ramp=3.0) as c:
        nbirth = c.subscriber.of("NBIRTH")[0]
        assert nbirth.topic == f"spBv1.0/{GROUP}/NBIRTH/{NODE}"
        assert nbirth.seq == 0
        node = {m.name: m for m in nbirth.metrics}
        assert node["bdSeq"].datatype == INT64
        assert node["Node Control/Rebirth"].value is False

        all_aliases: list[int] = []
        for device in ("m1013", "m0609"):
            birth = c.birth(device)
            by_name = {m.name: m for m in birth.metrics}
            assert list(by_name)[: len(EXPECTED_T2O)] == EXPECTED_T2O
            assert set(EXPECTED_O2T) <= set(by_name)
            all_aliases += [m.alias for m in birth.metrics if m.alias is not None]
            state = by_name["robot_state"]
            assert (state.datatype, state.value) == (UINT8, 13)
            assert state.properties["name"] == "STANDALONE_STANDBY"
            assert by_name["joint_motor_temperature/J 2"].properties["engUnit"] == "°C"
            assert by_name["controlbox_di/DI 1"].datatype == BOOLEAN
            assert by_name["controlbox_di/DI 1"].value is True
            assert by_name["tcp_position/Y"].value == f32(309.4)
            assert by_name["controller_version/minor"].value == 12
            assert by_name["Control/Holder"].value == ""
        assert len(all_aliases) == len(set(all_aliases)) == 2 * len(c.birth("m1013").metrics)

        # J1 ramps: wait for a few DDATA, then every value reported equals its frame's.
        j1 = c.aliases("m1013")["joint_position/J 1"]
        await c.subscriber.wait_for(
            lambda ms: sum(1 for m in ms if m.kind == "DDATA" and m.device == "m1013") >= 5
        )
        by_time: dict[int, set[float]] = {}  # frames received in the same ms (after a stall)
        for _, t, frame, _, _ in c.frames_seen("m1013"):
            by_time.setdefault(int(t * 1000), set()).add(f32(frame.joint_position[0]))
        checked = 0
        for message in c.subscriber.of("DDATA", "m1013"):
            for metric in message.metrics:
                if metric.alias == j1:
                    assert metric.timestamp in by_time
                    assert metric.value in by_time[metric.timestamp]
                    checked += 1
        assert checked >= 5
        assert not [m for m in c.subscriber.of("DDATA", "m0609") if m.metrics]  # it stood still

        # seq: NBIRTH 0, then one more per message of the node, modulo 256.
        ordered = node_messages(c.subscriber.snapshot())
        seqs = [m.seq for m in ordered]
        assert seqs == [i % 256 for i in range(len(seqs))]


async def test_bits_are_never_lost_and_state_names_follow(tmp_path: Path, plc_host: str) -> None:
    async with cell(tmp_path, plc_host) as c:
        panel = c.panels["m0609"]
        di = list(panel.produce_frame(0).controlbox_di)
        # Faster than the 10 Hz DDATA rate: several changes between two reports.
        for k in range(30):
            di[2] = k % 2 == 0
            panel.set(controlbox_di=tuple(di), robot_state=14 if k % 3 else 15)
            await asyncio.sleep(0.015)
        di[2] = True
        panel.set(controlbox_di=tuple(di), robot_state=16)
        alias = c.aliases("m0609")["controlbox_di/DI 3"]
        state_alias = c.aliases("m0609")["robot_state"]

        def reported(ms: list[Message], which: int) -> list[tuple[Any, int | None]]:
            return [
                (metric.value, metric.timestamp)
                for m in ms
                if m.kind == "DDATA" and m.device == "m0609"
                for metric in m.metrics
                if metric.alias == which
            ]

        def transitions(index: int | None) -> list[tuple[Any, int]]:
            out: list[tuple[Any, int]] = []
            previous = None
            for _, t, frame, _, _ in c.frames_seen("m0609"):
                value = frame.robot_state if index is None else frame.controlbox_di[index]
                if previous is not None and value != previous:
                    out.append((value, int(t * 1000)))
                previous = value
            return out

        await c.subscriber.wait_for(lambda ms: any(v == 16 for v, _ in reported(ms, state_alias)))
        await c.subscriber.wait_for(lambda ms: reported(ms, alias) == transitions(2))
        assert len(transitions(2)) >= 5  # the frames did show many of the toggles
        assert reported(c.subscriber.snapshot(), state_alias) == transitions(None)
        names = [
            metric.properties.get("name")
            for m in c.subscriber.of("DDATA", "m0609")
            for metric in m.metrics
            if metric.alias == state_alias
        ]
        assert set(names) <= {
            "STANDALONE_RUNNING",
            "COLLABORATIVE_STANDBY",
            "COLLABORATIVE_RUNNING",
        }


async def test_deadband_and_maximum_rate(tmp_path: Path, plc_host: str) -> None:
    async with cell(
        tmp_path,
        plc_host,
        ramp=2.0,
        sparkplug_deadbands="joint_position=0.5",
        sparkplug_max_rate_hz=5.0,
    ) as c:
        j1 = c.aliases("m1013")["joint_position/J 1"]
        birth_j1 = next(m.value for m in c.birth("m1013").metrics if m.alias == j1)

        def values(ms: list[Message]) -> list[float]:
            return [
                metric.value
                for m in ms
                if m.kind == "DDATA" and m.device == "m1013"
                for metric in m.metrics
                if metric.alias == j1
            ]

        await c.subscriber.wait_for(lambda ms: len(values(ms)) >= 4)
        reported = [birth_j1, *values(c.subscriber.snapshot())]
        steps = [abs(b - a) for a, b in itertools.pairwise(reported)]
        # 2 °/s sampled at 5 Hz moves 0.4° per report: only every second one passes 0.5°.
        assert all(step >= 0.5 - 1e-4 or step > 50 for step in steps), steps
        # No other joint moved, so nothing else was reported.
        others = {a for n, a in c.aliases("m1013").items() if n.startswith("joint_position/J ")}
        others.discard(j1)
        for message in c.subscriber.of("DDATA", "m1013"):
            assert not {metric.alias for metric in message.metrics} & others
        stamps = [m.timestamp or 0 for m in c.subscriber.of("DDATA", "m1013")]
        gaps_ms = [b - a for a, b in itertools.pairwise(stamps)]
        assert all(gap >= 200 - 2 for gap in gaps_ms), gaps_ms  # at most 5 per second


async def test_rebirth_on_ncmd(tmp_path: Path, plc_host: str) -> None:
    async with cell(tmp_path, plc_host) as c:
        bd_seq = next(m.value for m in c.subscriber.of("NBIRTH")[0].metrics if m.name == "bdSeq")
        c.subscriber.publish(
            f"spBv1.0/{GROUP}/NCMD/{NODE}",
            encode_command([("Node Control/Rebirth", None, BOOLEAN, True)]),
        )
        await c.subscriber.wait_for(
            lambda ms: (
                len([m for m in ms if m.kind == "NBIRTH"]) == 2
                and len([m for m in ms if m.kind == "DBIRTH"]) == 4
            )
        )
        second = c.subscriber.of("NBIRTH")[1]
        assert second.seq == 0
        assert next(m.value for m in second.metrics if m.name == "bdSeq") == bd_seq
        ordered = node_messages(c.subscriber.snapshot())
        after = ordered[ordered.index(second) :]
        assert [m.kind for m in after[:3]] == ["NBIRTH", "DBIRTH", "DBIRTH"]
        assert [m.seq for m in after[:3]] == [0, 1, 2]


async def _dcmd_outcome(c: Cell, device: str, metrics: list[Any], count: int) -> tuple[str, str]:
    aliases = c.aliases(device)
    c.subscriber.publish(f"spBv1.0/{GROUP}/DCMD/{NODE}/{device}", encode_command(metrics))

    def outcomes(ms: list[Message]) -> list[tuple[Any, Any]]:
        found = []
        for m in ms:
            if m.kind != "DDATA" or m.device != device:
                continue
            values = {metric.alias: metric.value for metric in m.metrics}
            if aliases["Write/Outcome"] in values:
                found.append((values[aliases["Write/Outcome"]], values[aliases["Write/Reason"]]))
        return found

    await c.subscriber.wait_for(lambda ms: len(outcomes(ms)) >= count)
    result: tuple[str, str] = outcomes(c.subscriber.snapshot())[count - 1]
    return result


async def test_dcmd_write_through_the_pipeline(tmp_path: Path, plc_host: str) -> None:
    async with cell(tmp_path, plc_host, mqtt_writes=True) as c:
        do4 = c.aliases("m1013")["command/controlbox_do/DO 4"]
        write = [(None, do4, BOOLEAN, True)]
        outcome, reason = await _dcmd_outcome(c, "m1013", write, 1)
        assert outcome == "refused"
        assert "take control" in reason
        assert not c.panels["m1013"].command_image().controlbox_do[3]

        outcome, _ = await _dcmd_outcome(c, "m1013", [("Control/Take", None, BOOLEAN, True)], 2)
        assert outcome == "granted"
        outcome, reason = await _dcmd_outcome(c, "m1013", write, 3)
        assert (outcome, reason) == ("confirmed", "")
        assert c.panels["m1013"].command_image().controlbox_do[3]
        robot = c.running.service.robots["m1013"]
        latest = robot.frames.latest
        assert latest is not None and latest[2].controlbox_do[3]
        # The O→T image and the holder were reported back too.
        aliases = c.aliases("m1013")

        def reported(ms: list[Message], alias: int) -> list[Any]:
            return [
                metric.value
                for m in ms
                if m.kind == "DDATA" and m.device == "m1013"
                for metric in m.metrics
                if metric.alias == alias
            ]

        await c.subscriber.wait_for(lambda ms: True in reported(ms, do4))
        holders = reported(c.subscriber.snapshot(), aliases["Control/Holder"])
        assert holders and holders[-1].startswith("mqtt:")
        # An invalid value (a number for a bit) is refused whole, naming nothing applied.
        outcome, reason = await _dcmd_outcome(
            c, "m1013", [(None, aliases["command/analog_output/AO 0"], FLOAT, 99.0)], 4
        )
        assert outcome == "invalid"
        assert "analog_output" in reason
        # The other robot was not touched, and MQTT's control is m1013's only.
        outcome, _ = await _dcmd_outcome(
            c, "m0609", [(None, c.aliases("m0609")["command/controlbox_do/DO 1"], BOOLEAN, True)], 1
        )
        assert outcome == "refused"
    with closing(sqlite3.connect(tmp_path / "hmi.db")) as db:
        rows = db.execute(
            "SELECT action, user, outcome, robot, origin FROM audit ORDER BY id"
        ).fetchall()
    writes = [r for r in rows if r[0] == "write"]
    assert [(r[2], r[3]) for r in writes] == [
        ("refused", "m1013"),
        ("confirmed", "m1013"),
        ("invalid", "m1013"),
        ("refused", "m0609"),
    ]
    assert all(r[1].startswith("mqtt:") for r in rows)
    assert all(r[4].startswith(f"MQTT DCMD spBv1.0/{GROUP}/DCMD/{NODE}/") for r in writes)
    assert ("control.take", writes[0][1], "granted", "m1013") in [r[:4] for r in rows]


async def test_dcmd_refused_when_writes_are_off_and_metrics(tmp_path: Path, plc_host: str) -> None:
    async with cell(tmp_path, plc_host) as c:
        take = [("Control/Take", None, BOOLEAN, True)]
        outcome, reason = await _dcmd_outcome(c, "m1013", take, 1)
        assert outcome == "refused"
        assert "--mqtt-writes" in reason
        assert c.running.service.robots["m1013"].control.holder is None
        text = await c.running.metrics()
        assert "cobot_hmi_sparkplug_broker_connected 1.0" in text
        assert 'cobot_hmi_sparkplug_messages_total{type="NBIRTH"} 1.0' in text
        assert 'cobot_hmi_sparkplug_messages_total{robot="m1013",type="DBIRTH"} 1.0' in text
        assert 'cobot_hmi_sparkplug_frames_dropped_total{robot="m0609"} 0.0' in text
        assert 'cobot_hmi_sparkplug_commands_total{outcome="refused"} 1.0' in text
        await eventually(lambda: edge_node_of(c.running.service) is not None)
