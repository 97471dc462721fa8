"""The plant's host application rules (``cobot_hmi.plant.host``), pure: messages in, what to
publish and record out. Payloads are written here byte by byte (the protobuf wire format of
Sparkplug B's ``Payload``), and the rebirth requests read back with the tests' own reader
(``mosquitto_support.decode_payload``), so neither side is checked by the code under test."""

from __future__ import annotations

import json
import struct
from typing import Any

import pytest

from cobot_hmi.plant.host import HISTORY_MARGIN_MS, HostApplication, state_payload
from cobot_hmi.plant.model import alarm_figures, shift_figures
from mosquitto_support import decode_payload, encode_varint, field_key

BOOLEAN, INT8, INT32, INT64, UINT8, FLOAT, DOUBLE, STRING = 11, 1, 3, 4, 5, 9, 10, 12
T0 = 1_800_000_000_000
GROUP, NODE = "plant", "cell-1"


def _bytes(number: int, raw: bytes) -> bytes:
    return field_key(number, 2) + encode_varint(len(raw)) + raw


def metric(
    name: str | None = None,
    *,
    alias: int | None = None,
    datatype: int | None = None,
    value: Any = None,
    timestamp: int | None = None,
    historical: bool = False,
) -> bytes:
    out = b""
    if name is not None:
        out += _bytes(1, name.encode())
    if alias is not None:
        out += field_key(2, 0) + encode_varint(alias)
    if timestamp is not None:
        out += field_key(3, 0) + encode_varint(timestamp)
    if datatype is not None:
        out += field_key(4, 0) + encode_varint(datatype)
    if historical:
        out += field_key(5, 0) + encode_varint(1)
    if isinstance(value, bool):
        out += field_key(14, 0) + encode_varint(int(value))
    elif isinstance(value, float):
        out += field_key(12, 5) + struct.pack("<f", value)
    elif isinstance(value, str):
        out += _bytes(15, value.encode())
    elif isinstance(value, int):
        field = 11 if datatype == INT64 else 10
        mask = 0xFFFFFFFF if field == 10 else 2**64 - 1
        out += field_key(field, 0) + encode_varint(value & mask)
    return out


def payload(*metrics: bytes, seq: int | None, timestamp: int = T0) -> bytes:
    out = field_key(1, 0) + encode_varint(timestamp)
    for m in metrics:
        out += _bytes(2, m)
    if seq is not None:
        out += field_key(3, 0) + encode_varint(seq)
    return out


def topic(kind: str, device: str | None = None, node: str = NODE) -> str:
    return f"spBv1.0/{GROUP}/{kind}/{node}" + (f"/{device}" if device else "")


def nbirth(bd_seq: int = 3) -> bytes:
    return payload(
        metric("bdSeq", datatype=INT64, value=bd_seq),
        metric("Node Control/Rebirth", datatype=BOOLEAN, value=False),
        metric("Node Info/HMI URL", datatype=STRING, value="https://cell-1.example:8443/"),
        seq=0,
    )


def dbirth(seq: int) -> bytes:
    return payload(
        metric("robot_state", alias=1001, datatype=UINT8, value=16, timestamp=T0),
        metric("temperature", alias=1002, datatype=INT8, value=-5, timestamp=T0),
        metric("Alarm/estop/Active", alias=1003, datatype=BOOLEAN, value=False, timestamp=T0),
        metric("Alarm/estop/Priority", alias=1004, datatype=STRING, value="critical"),
        metric("Alarm/estop/Text", alias=1005, datatype=STRING, value="Emergency stop"),
        seq=seq,
    )


def born(host: HostApplication, now_s: float = 100.0) -> None:
    assert not host.on_message(topic("NBIRTH"), nbirth(), now_s).publish
    assert not host.on_message(topic("DBIRTH", "m1013"), dbirth(1), now_s).publish


def rebirth_of(answer_publish: list[Any]) -> list[str]:
    """The nodes each outgoing message asks to rebirth (read with the tests' own decoder)."""
    return [topic for topic, _ in rebirths_since(answer_publish)]


def rebirths_since(answer_publish: list[Any]) -> list[tuple[str, int | None]]:
    """Each rebirth request's node and the time its alarm transitions are asked again from."""
    found = []
    for out in answer_publish:
        message = decode_payload(out.topic, out.payload, 0.0)
        assert message.kind == "NCMD"
        metrics = [(m.name, m.value) for m in message.metrics]
        assert metrics[0] == ("Node Control/Rebirth", True)
        since = dict(metrics[1:]).get("Node Control/Alarm History Since")
        assert len(metrics) == 1 + (since is not None)
        found.append((out.topic, since))
    return found


def test_a_birth_then_data_in_order_is_live_and_asks_nothing() -> None:
    host = HostApplication("plant-host")
    born(host)
    answer = host.on_message(
        topic("DDATA", "m1013"), payload(metric(alias=1001, value=14), seq=2), 101.0
    )
    assert not answer.publish
    node = host.nodes[(GROUP, NODE)]
    assert node.online and node.bd_seq == 3
    assert node.text("Node Info/HMI URL") == "https://cell-1.example:8443/"
    device = node.devices["m1013"]
    assert device.online and device.state() == "STANDALONE_RUNNING"
    assert device.value("temperature") == -5  # INT8 given its sign back
    assert [s.metric for s in answer.samples] == ["robot_state"]


def test_a_seq_gap_asks_for_a_rebirth_rate_limited() -> None:
    host = HostApplication("plant-host", rebirth_interval_s=5.0)
    born(host)
    gap = host.on_message(
        topic("DDATA", "m1013"), payload(metric(alias=1001, value=13), seq=5), 101
    )
    assert rebirth_of(gap.publish) == [topic("NCMD")]
    # The data itself is still taken: it is the cell's, only something before it was lost.
    assert host.nodes[(GROUP, NODE)].devices["m1013"].state() == "STANDALONE_STANDBY"
    again = host.on_message(
        topic("DDATA", "m1013"), payload(metric(alias=1001, value=14), seq=9), 102
    )
    assert not again.publish and host.rebirths_held == 1
    later = host.on_message(
        topic("DDATA", "m1013"), payload(metric(alias=1001, value=14), seq=20), 106.5
    )
    assert rebirth_of(later.publish) == [topic("NCMD")]
    assert host.rebirths["seq gap"] == 2
    # seq wraps at 256 without a gap.
    host2 = HostApplication("h")
    host2.on_message(topic("NBIRTH"), nbirth(), 1.0)
    host2.on_message(topic("DBIRTH", "m1013"), dbirth(1), 1.0)
    for seq in [*range(2, 256), 0, 1]:
        ok = host2.on_message(
            topic("DDATA", "m1013"), payload(metric(alias=1001, value=1), seq=seq), 2
        )
        assert not ok.publish, seq


def test_an_unknown_alias_asks_for_a_rebirth() -> None:
    host = HostApplication("plant-host")
    born(host)
    answer = host.on_message(
        topic("DDATA", "m1013"), payload(metric(alias=4242, value=1), seq=2), 101
    )
    assert rebirth_of(answer.publish) == [topic("NCMD")]
    assert host.rebirths["unknown alias"] == 1


def test_data_before_a_birth_asks_for_a_rebirth() -> None:
    host = HostApplication("plant-host")
    answer = host.on_message(
        topic("DDATA", "m1013", node="cell-9"), payload(metric(alias=1, value=1), seq=7), 50
    )
    assert rebirth_of(answer.publish) == [topic("NCMD", node="cell-9")]
    assert not host.nodes[(GROUP, "cell-9")].online
    # A node born, a device not: its DDATA asks too.
    other = HostApplication("plant-host")
    other.on_message(topic("NBIRTH"), nbirth(), 60)
    answer = other.on_message(
        topic("DDATA", "m0609"), payload(metric(alias=2001, value=1), seq=1), 60
    )
    assert rebirth_of(answer.publish) == [topic("NCMD")]
    assert other.rebirths["before birth"] == 1


def test_ndeath_needs_the_births_bdseq_and_marks_offline_since() -> None:
    host = HostApplication("plant-host")
    born(host)
    stale = payload(metric("bdSeq", datatype=INT64, value=2), seq=None, timestamp=T0 + 500)
    host.on_message(topic("NDEATH"), stale, 110)
    node = host.nodes[(GROUP, NODE)]
    assert node.online and host.stale_deaths == 1
    death = payload(metric("bdSeq", datatype=INT64, value=3), seq=None, timestamp=T0 + 900)
    host.on_message(topic("NDEATH"), death, 111)
    assert not node.online and node.since_ms == T0 + 900
    device = node.devices["m1013"]
    assert not device.online and device.since_ms == T0 + 900
    assert device.state() == "COLLABORATIVE_RUNNING"  # the last values kept (greyed)
    # After a death, data is data before a birth.
    answer = host.on_message(
        topic("DDATA", "m1013"), payload(metric(alias=1001, value=1), seq=2), 200
    )
    assert rebirth_of(answer.publish) == [topic("NCMD")]


def test_ddeath_marks_the_device_offline_since() -> None:
    host = HostApplication("plant-host")
    born(host)
    host.on_message(topic("DDEATH", "m1013"), payload(seq=2, timestamp=T0 + 70), 101)
    device = host.nodes[(GROUP, NODE)].devices["m1013"]
    assert not device.online and device.since_ms == T0 + 70
    assert device.state() == "COLLABORATIVE_RUNNING"
    assert host.nodes[(GROUP, NODE)].online


def test_historical_metrics_are_recorded_in_time_order_never_live() -> None:
    host = HostApplication("plant-host")
    born(host)
    live = host.on_message(
        topic("DDATA", "m1013"),
        payload(metric(alias=1003, value=True, timestamp=T0 + 9000), seq=2),
        101,
    )
    assert [t.active for t in live.transitions] == [True]
    replay = host.on_message(
        topic("DDATA", "m1013"),
        payload(
            metric(alias=1001, value=2, timestamp=T0 + 1000, historical=True),
            metric(alias=1003, value=True, timestamp=T0 + 2000, historical=True),
            metric(alias=1003, value=False, timestamp=T0 + 3000, historical=True),
            seq=3,
        ),
        102,
    )
    device = host.nodes[(GROUP, NODE)].devices["m1013"]
    assert device.state() == "COLLABORATIVE_RUNNING"  # not the historical SAFE_OFF
    assert [a.alarm for a in device.alarms_active()] == ["estop"]
    assert all(s.historical for s in replay.samples)
    log = host.alarms.between(T0, T0 + 10_000)
    assert [(t.time_ms - T0, t.active, t.historical) for t in log] == [
        (2000, True, True),
        (3000, False, True),
        (9000, True, False),
    ]
    assert log[0].priority == "critical" and log[0].text == "Emergency stop"


def test_alarm_figures_flood_and_bad_actors() -> None:
    host = HostApplication("plant-host")
    born(host)
    seq = 2
    for i in range(12):  # 12 activations in 6 minutes: a flood
        for active in (True, False):
            stamp = T0 + i * 30_000 + (0 if active else 1000)
            host.on_message(
                topic("DDATA", "m1013"),
                payload(metric(alias=1003, value=active, timestamp=stamp), seq=seq),
                101,
            )
            seq += 1
    figures = alarm_figures(host.alarms.between(T0, T0 + 600_000), T0, T0 + 600_000)
    assert len(figures) == 1
    cell = figures[0]
    assert cell.flood and cell.peak_per_10_min == 12
    assert abs(cell.alarms_per_10_min - 12.0) < 1e-9
    assert cell.bad_actors == [("m1013", "estop", 12)]


def test_state_payload_is_sparkplug_json() -> None:
    assert json.loads(state_payload(True, 1234)) == {"online": True, "timestamp": 1234}
    host = HostApplication("plant-a", frozenset({"line-2", "line-1"}))
    assert host.subscriptions == [
        "spBv1.0/STATE/plant-a",
        "spBv1.0/line-1/#",
        "spBv1.0/line-2/#",
    ]
    assert not host.on_message("spBv1.0/other/NBIRTH/x", nbirth(), 1.0).samples
    assert host.on_message("spBv1.0/line-1/NBIRTH/x", b"\xff\xff not protobuf", 1.0).samples == []
    assert host.bad_messages == 1


def test_shift_figures_time_in_each_state_group_and_cycles() -> None:
    start, end = 1_000_000, 1_000_000 + 3_600_000
    states = [
        (start - 60_000, "STANDALONE_STANDBY"),  # what the shift started in
        (start + 600_000, "STANDALONE_RUNNING"),
        (start + 3_000_000, "SAFE_OFF"),
        (start + 3_300_000, "INTERRUPTED"),
        (end + 5_000, "STANDALONE_RUNNING"),  # after the shift: not counted
    ]
    figures = shift_figures(states, [30.0, 31.0, 32.0], start, end)
    assert figures.seconds == {
        "standby": 600.0,
        "running": 2400.0,
        "error": 300.0,
        "stopped": 300.0,
        "unknown": 0.0,
    }
    assert figures.cycles == 3 and figures.mean_cycle_s == pytest.approx(31.0)
    unknown_start = shift_figures([(start + 1000, "STANDALONE_RUNNING")], [], start, end)
    assert unknown_start.seconds["unknown"] == pytest.approx(1.0)
    assert unknown_start.mean_cycle_s is None


def test_a_gap_asks_for_the_alarm_transitions_since_the_last_message_in_order() -> None:
    host = HostApplication("plant-host")
    born(host)
    host.on_message(
        topic("DDATA", "m1013"),
        payload(metric(alias=1001, value=14), seq=2, timestamp=T0 + 5000),
        101,
    )
    gap = host.on_message(
        topic("DDATA", "m1013"),
        payload(metric(alias=1001, value=13), seq=7, timestamp=T0 + 9000),
        102,
    )
    assert rebirths_since(gap.publish) == [(topic("NCMD"), T0 + 5000 - HISTORY_MARGIN_MS)]
    # The cell answers with its births (left out here) and the transitions since, as
    # historical: one the plant had heard live is kept once, the ones it missed go where they
    # happened.
    host.on_message(
        topic("DDATA", "m1013"),
        payload(metric(alias=1003, value=True, timestamp=T0 + 4000), seq=8, timestamp=T0 + 9500),
        103,
    )
    replay = host.on_message(
        topic("DDATA", "m1013"),
        payload(
            metric(alias=1003, value=True, timestamp=T0 + 4000, historical=True),
            metric(alias=1003, value=False, timestamp=T0 + 6000, historical=True),
            metric(alias=1003, value=True, timestamp=T0 + 7000, historical=True),
            metric(alias=1003, value=False, timestamp=T0 + 8000, historical=True),
            seq=9,
        ),
        105,
    )
    log = host.alarms.between(T0, T0 + 60_000)
    assert [(t.time_ms - T0, t.active) for t in log] == [
        (4000, True),
        (6000, False),
        (7000, True),
        (8000, False),
    ]
    assert [s.time_ms - T0 for s in replay.samples] == [6000, 7000, 8000]
    assert [t.time_ms - T0 for t in replay.transitions] == [6000, 7000, 8000]
    # Sent again a second time (another rebirth): nothing new.
    again = host.on_message(
        topic("DDATA", "m1013"),
        payload(metric(alias=1003, value=False, timestamp=T0 + 6000, historical=True), seq=10),
        106,
    )
    assert not again.transitions and not again.samples and len(host.alarms) == 4


def test_a_reconnected_host_asks_every_node_it_knew_for_a_rebirth() -> None:
    host = HostApplication("plant-host")
    assert host.on_reconnect(50.0) == []  # the first connection: nobody known yet
    born(host)
    host.on_message(topic("NBIRTH", node="cell-2"), nbirth(), 100.0)
    host.on_message(
        topic("NDEATH", node="cell-2"),
        payload(metric("bdSeq", datatype=INT64, value=3), seq=None),
        100.5,
    )
    asked = rebirths_since(host.on_reconnect(101.0))
    assert asked == [(topic("NCMD"), T0 - HISTORY_MARGIN_MS)]  # cell-2 is dead: not asked
    assert host.rebirths["reconnect"] == 1


def test_an_alarm_born_with_its_priority_and_text_after_it_is_told_with_them() -> None:
    host = HostApplication("plant-host")
    host.on_message(topic("NBIRTH"), nbirth(), 1.0)
    answer = host.on_message(
        topic("DBIRTH", "m1013"),
        payload(
            metric(
                "Alarm/protective_stop/Active",
                alias=1010,
                datatype=BOOLEAN,
                value=True,
                timestamp=T0,
            ),
            metric("Alarm/protective_stop/Priority", alias=1011, datatype=STRING, value="high"),
            metric(
                "Alarm/protective_stop/Text", alias=1012, datatype=STRING, value="Protective stop"
            ),
            metric("Health/J3/Life Used", alias=1013, datatype=DOUBLE, value=None),
            seq=1,
        ),
        1.0,
    )
    [transition] = answer.transitions
    assert (transition.priority, transition.text) == ("high", "Protective stop")
    device = host.nodes[(GROUP, NODE)].devices["m1013"]
    assert device.health() == {}  # Null: not known yet


def test_a_held_rebirth_request_goes_out_once_the_rate_limit_allows() -> None:
    host = HostApplication("plant-host", rebirth_interval_s=5.0)
    born(host)
    host.on_message(topic("DDATA", "m1013"), payload(metric(alias=1001, value=13), seq=4), 101)
    held = host.on_message(
        topic("DDATA", "m1013"),
        payload(metric(alias=1001, value=14), seq=9, timestamp=T0 + 2000),
        102,
    )
    assert not held.publish and host.rebirths_held == 1
    assert host.due(105.9) == []
    # A quiet node brings nothing more: the request goes out by the clock, asking for the
    # transitions since before the first gap.
    assert rebirths_since(host.due(106.0)) == [(topic("NCMD"), T0 - HISTORY_MARGIN_MS)]
    assert host.due(115.9) == []
    # No NBIRTH answered it (a broker cluster re-forming can lose a request): asked again, for
    # the same transitions; the births end the asking.
    assert rebirths_since(host.due(116.0)) == [(topic("NCMD"), T0 - HISTORY_MARGIN_MS)]
    assert host.rebirths["unanswered"] == 1
    born(host, 117.0)
    assert host.due(200.0) == []
    # A node that never answers is asked again three times, not forever.
    host.on_message(topic("DDATA", "m1013"), payload(metric(alias=1001, value=13), seq=9), 300)
    assert [len(host.due(300.0 + 10.0 * n)) for n in range(1, 6)] == [1, 1, 1, 0, 0]


def test_a_request_is_unanswered_only_once_what_came_after_it_has_been_handled() -> None:
    """A plant behind its messages may hold the NBIRTH that answers, received and not yet
    handled: it does not ask again until it has handled what came REBIRTH_ANSWER_S after."""
    host = HostApplication("plant-host", rebirth_interval_s=5.0)
    born(host)
    gap = host.on_message(
        topic("DDATA", "m1013"), payload(metric(alias=1001, value=13), seq=4), 101
    )
    assert len(gap.publish) == 1 and host.unanswered == 1
    assert host.due(130.0, seen_until_s=110.9) == []
    assert len(host.due(130.0, seen_until_s=111.0)) == 1
    assert host.rebirths["unanswered"] == 1
    born(host, 131.0)
    assert host.unanswered == 0
