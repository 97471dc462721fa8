"""Issue 13, the alarm engine's pure parts: the ISA-18.2 state machine (against a reference
table, with Hypothesis), limits with deadband and on/off delays on synthetic frames, the
engine's events and its quiet hot path, labels and the write summary, user alarm settings,
tag names as CSV."""

from __future__ import annotations

import itertools
import math
import tracemalloc
from collections.abc import Callable
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cobot_hmi.codec import Frame, zero_frame
from cobot_hmi.service.alarms.conditions import (
    CAME,
    UNCHANGED,
    WENT,
    BitCondition,
    Condition,
    LimitCondition,
    StateCondition,
)
from cobot_hmi.service.alarms.definitions import PRIORITY_COLOURS, Priority
from cobot_hmi.service.alarms.engine import AlarmEngine, AlarmRefusedError, UserAlarm
from cobot_hmi.service.alarms.state import (
    AlarmState,
    AlarmStatus,
    NothingToAcknowledgeError,
    Transition,
)
from cobot_hmi.service.config.loading import load_settings
from cobot_hmi.service.labels import element_label, labels_of, write_summary
from cobot_hmi.service.service_settings import ServiceSettings, SettingsError
from cobot_hmi.service.storage.store import iso8601
from cobot_hmi.service.storage.tags import POINTS_BY_KEY, TagError, check_tags, from_csv, to_csv

A, B, C, D = (
    AlarmState.NORMAL,
    AlarmState.ACTIVE_UNACKNOWLEDGED,
    AlarmState.ACTIVE_ACKNOWLEDGED,
    AlarmState.RETURNED_UNACKNOWLEDGED,
)

# --------------------------------------------------------------------------- state machine

# The standard's diagram, written out once more independently of the module's tables.
REFERENCE: dict[tuple[AlarmState, str], AlarmState] = {
    (A, "come"): B,
    (A, "go"): A,
    (A, "ack"): A,
    (B, "come"): B,
    (B, "go"): D,
    (B, "ack"): C,
    (C, "come"): C,
    (C, "go"): A,
    (C, "ack"): C,
    (D, "come"): B,
    (D, "go"): D,
    (D, "ack"): A,
}


@settings(max_examples=300, deadline=None)
@given(st.lists(st.sampled_from(["come", "go", "ack", "shelve", "unshelve", "tick"]), max_size=40))
def test_state_machine_follows_isa_18_2(operations: list[str]) -> None:
    status = AlarmStatus()
    expected = A
    shelved_until: float | None = None
    cleared_while_shelved = False
    for step, operation in enumerate(operations):
        t = float(step)
        before = status.state
        if operation in ("come", "go"):
            transition = status.process(operation == "come", t)
            expected = REFERENCE[(expected, operation)]
            if before != expected:
                assert transition is (
                    Transition.ACTIVATED if operation == "come" else Transition.CLEARED
                )
                if shelved_until is not None and operation == "go":
                    cleared_while_shelved = True
                elif cleared_while_shelved:  # it came again: a new occurrence, annunciated
                    shelved_until = None
                    cleared_while_shelved = False
            else:
                assert transition is None
        elif operation == "ack":
            if expected is A:
                with pytest.raises(NothingToAcknowledgeError):
                    status.acknowledge("olivia", None, t)
            else:
                transition = status.acknowledge("olivia", "seen", t)
                expected = REFERENCE[(expected, "ack")]
                assert (transition is Transition.ACKNOWLEDGED) == (before != expected)
        elif operation == "shelve":
            status.shelve("olivia", "maintenance", t + 3, t)
            shelved_until = t + 3
            cleared_while_shelved = False
        elif operation == "unshelve":
            assert (status.unshelve(t) is not None) == (shelved_until is not None)
            shelved_until = None
            cleared_while_shelved = False
        else:
            expired = status.expire(t)
            if shelved_until is not None and t >= shelved_until:
                assert expired is Transition.SHELVE_EXPIRED
                shelved_until = None
                cleared_while_shelved = False
            else:
                assert expired is None
        assert status.state is expected
        # Invariants: active iff B or C; acknowledged iff A or C; shelving is beside the state.
        assert status.state.active == (expected in (B, C))
        assert status.state.acknowledged == (expected in (A, C))
        assert status.shelved == (shelved_until is not None)
        if expected in (B, D):
            assert status.acknowledged_at is None
    restored = AlarmStatus.from_json(status.to_json())
    assert restored == status


def test_acknowledge_records_who_and_a_new_activation_forgets_it() -> None:
    status = AlarmStatus()
    status.process(True, 1.0)
    status.acknowledge("olivia", "seen it", 2.0)
    assert (status.acknowledged_by, status.ack_comment, status.acknowledged_at) == (
        "olivia",
        "seen it",
        2.0,
    )
    status.process(False, 3.0)
    assert status.state is A
    status.process(True, 4.0)
    assert status.state is B
    assert status.acknowledged_by is None and status.activated_at == 4.0


# --------------------------------------------------------------------------- conditions


def _temperatures(*values: float) -> object:
    return zero_frame()._replace(joint_motor_temperature=(*values, 0.0, 0.0, 0.0, 0.0, 0.0)[:6])


def test_limit_with_deadband_does_not_chatter() -> None:
    condition = LimitCondition(
        "joint_motor_temperature.0", "joint_motor_temperature", 0, high=80.0, low=None, deadband=2.0
    )
    seen = [
        condition.update(_temperatures(value), float(i))  # type: ignore[arg-type]
        for i, value in enumerate([79.0, 80.0, 80.5, 79.5, 78.5, 80.2, 77.9, 78.5, 80.1])
    ]
    # 80.0 is not above 80; 80.5 comes; 79.5 and 78.5 stay inside the deadband (clear below
    # 78); 77.9 goes; 78.5 stays clear; 80.1 comes again.
    assert seen == [
        UNCHANGED,
        UNCHANGED,
        CAME,
        UNCHANGED,
        UNCHANGED,
        UNCHANGED,
        WENT,
        UNCHANGED,
        CAME,
    ]


def test_low_limit_and_nan_keeps_an_active_alarm() -> None:
    condition = LimitCondition(
        "analog_input.0", "analog_input", 0, high=None, low=4.0, deadband=0.5
    )
    frame = zero_frame()
    assert condition.update(frame._replace(analog_input=(3.9, 0.0)), 0.0) == CAME
    assert condition.update(frame._replace(analog_input=(math.nan, 0.0)), 1.0) == UNCHANGED
    assert condition.update(frame._replace(analog_input=(4.4, 0.0)), 2.0) == UNCHANGED
    assert condition.update(frame._replace(analog_input=(4.5, 0.0)), 3.0) == WENT


def test_on_and_off_delays_run_on_frame_time() -> None:
    condition = BitCondition(
        "controlbox_di.2", "controlbox_di", 2, active_when=True, on_delay_s=1.0, off_delay_s=0.5
    )
    on = zero_frame()._replace(controlbox_di=(False, False, True, *(False,) * 13))
    off = zero_frame()
    assert condition.update(on, 10.0) == UNCHANGED
    assert condition.update(on, 10.9) == UNCHANGED
    assert condition.update(off, 10.95) == UNCHANGED  # the blip restarts the on-delay
    assert condition.update(on, 11.0) == UNCHANGED
    assert condition.update(on, 11.99) == UNCHANGED
    assert condition.update(on, 12.0) == CAME
    assert condition.update(off, 12.1) == UNCHANGED
    assert condition.update(on, 12.2) == UNCHANGED  # back before the off-delay: stays
    assert condition.update(off, 12.3) == UNCHANGED
    assert condition.update(off, 12.8) == WENT


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.floats(min_value=60.0, max_value=100.0, allow_nan=False), min_size=1, max_size=60),
    st.floats(min_value=0.0, max_value=5.0),
)
def test_limit_alarm_is_active_exactly_as_the_hysteresis_says(
    values: list[float], deadband: float
) -> None:
    condition = LimitCondition(
        "joint_motor_temperature.0",
        "joint_motor_temperature",
        0,
        high=80.0,
        low=None,
        deadband=deadband,
    )
    active = False
    for i, value in enumerate(values):
        change = condition.update(_temperatures(value), float(i))  # type: ignore[arg-type]
        if not active and value > 80.0:
            active = True
            assert change == CAME
        elif active and value <= 80.0 - deadband:
            active = False
            assert change == WENT
        else:
            assert change == UNCHANGED
        assert condition.active is active


# --------------------------------------------------------------------------- engine


def _engine(**overrides: object) -> tuple[AlarmEngine, list[dict[str, object]]]:
    published: list[dict[str, object]] = []
    options: dict[str, object] = {
        "motor_temperature_c": 80.0,
        "motor_temperature_deadband_c": 2.0,
        "gap_rate_per_min": 10.0,
        "connection_delay_s": 2.0,
        "shelve_max_s": 3600.0,
        "publish": published.append,
        "tags": lambda: {"joint_motor_temperature.2": "wrist motor", "controlbox_di.2": "door"},
        "clock": lambda: 1000.0,
    }
    options.update(overrides)
    return AlarmEngine("left", **options), published  # type: ignore[arg-type]


def test_engine_emergency_stop_on_the_first_frame_that_shows_it() -> None:
    engine, _ = _engine()
    running = zero_frame()._replace(robot_state=14, servo_on=True)
    estop = zero_frame()._replace(robot_state=0, emergency_stopped=True)
    assert engine.observe(running, 1.0) is None
    events = engine.observe(estop, 1.01)
    assert events is not None
    [event] = events
    assert event["kind"] == "alarm" and event["transition"] == "activated"
    alarm = event["alarm"]
    assert isinstance(alarm, dict)
    assert alarm["id"] == "left:emergency_stop"
    assert alarm["state"] == "active_unacknowledged"
    assert alarm["priority"] == "critical" and alarm["colour"] == "red"
    assert alarm["activated_at"] == 1.01
    assert engine.observe(estop, 1.02) is None
    acknowledged, changed = engine.acknowledge("left:emergency_stop", "olivia", "on it")
    assert changed and acknowledged["state"] == "active_acknowledged"
    assert acknowledged["acknowledged_by"] == "olivia" and acknowledged["ack_comment"] == "on it"
    events = engine.observe(zero_frame()._replace(robot_state=2), 2.0)  # SAFE_OFF after reset
    assert events is not None
    kinds = {(e["alarm"]["key"], e["transition"]) for e in events}  # type: ignore[index]
    assert kinds == {("emergency_stop", "cleared"), ("safe_off", "activated")}
    assert engine.find("left:emergency_stop").status.state is A
    with pytest.raises(AlarmRefusedError):
        engine.acknowledge("left:emergency_stop", "olivia", None)


def test_engine_motor_temperature_carries_label_and_tag() -> None:
    engine, _ = _engine()
    hot = zero_frame()._replace(
        robot_state=14, joint_motor_temperature=(30.0, 30.0, 81.5, 30.0, 30.0, 30.0)
    )
    events = engine.observe(hot, 5.0)
    assert events is not None
    alarm = events[0]["alarm"]
    assert isinstance(alarm, dict)
    assert alarm["key"] == "motor_temperature.2"
    assert alarm["label"] == "J 3" and alarm["tag"] == "wrist motor"
    assert alarm["message"] == "J 3 (wrist motor) = 81.5 °C"
    assert alarm["value"] == 81.5 and alarm["high"] == 80.0 and alarm["unit"] == "°C"


def test_engine_user_alarm_with_delays() -> None:
    user = UserAlarm(
        name="door-open",
        field="controlbox_di",
        index=2,
        active_when=True,
        on_delay_s=0.5,
        priority="high",
        message="Cell door open",
    )
    engine, _ = _engine(user_alarms=(user,))
    door = zero_frame()._replace(robot_state=14, controlbox_di=(False, False, True, *(False,) * 13))
    assert engine.observe(door, 1.0) is None
    events = engine.observe(door, 1.5)
    assert events is not None
    alarm = events[0]["alarm"]
    assert isinstance(alarm, dict)
    assert alarm["id"] == "left:user.door-open" and alarm["name"] == "Cell door open"
    assert alarm["label"] == "DI 3" and alarm["tag"] == "door" and alarm["priority"] == "high"
    assert alarm["colour"] == PRIORITY_COLOURS[Priority.HIGH]


def _peak_bytes(function: Callable[[Frame, float], object], frame: Frame) -> int:
    """The most memory ``function(frame, 1.0)`` 1000 times has held at once beyond the start."""
    for _ in itertools.repeat(None, 10):  # warm up (caches, first-call work)
        function(frame, 1.0)
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        start, _ = tracemalloc.get_traced_memory()
        for _ in itertools.repeat(None, 1000):  # no int objects: repeat, not range
            function(frame, 1.0)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    return peak - start


def _nothing(frame: Frame, time_s: float) -> None:
    return None


def _one_list(frame: Frame, time_s: float) -> list[float]:
    return [time_s]


def test_engine_hot_path_allocates_nothing_when_nothing_changes() -> None:
    user = UserAlarm(name="pressure", field="analog_input", index=0, high=18.0, low=4.5)
    engine, _ = _engine(user_alarms=(user,))
    frame = zero_frame()._replace(
        robot_state=14, joint_motor_temperature=(30.0,) * 6, analog_input=(10.0, 0.0)
    )
    assert engine.observe(frame, 1.0) is None
    baseline = _peak_bytes(_nothing, frame)  # the measurement's own allocation
    assert _peak_bytes(_one_list, frame) > baseline, "the measure sees one small list"
    assert _peak_bytes(engine.observe, frame) <= baseline
    # Equal frames that are new objects (evaluated each time, not skipped as the same one).
    equal = itertools.cycle((frame._replace(), frame._replace()))
    assert _peak_bytes(lambda _, time_s: engine.observe(next(equal), time_s), frame) <= baseline


def test_engine_evaluates_the_same_frame_again_only_while_a_delay_runs() -> None:
    """The originator hands on the same ``Frame`` while the robot's bytes do not change: that
    frame again changes nothing unless a condition's delay runs (then time alone can)."""
    user = UserAlarm(
        name="door-open", field="controlbox_di", index=2, active_when=True, on_delay_s=0.5
    )
    engine, _ = _engine(user_alarms=(user,))
    calm = zero_frame()._replace(robot_state=14)
    assert engine.observe(calm, 1.0) is None
    assert engine.observe(calm, 5.0) is None
    door = zero_frame()._replace(robot_state=14, controlbox_di=(False, False, True, *(False,) * 13))
    assert engine.observe(door, 2.0) is None, "the on-delay runs"
    assert engine.observe(door, 2.2) is None
    events = engine.observe(door, 2.5)  # the same object, later: the delay ran out
    assert events is not None
    assert events[0]["alarm"]["key"] == "user.door-open"  # type: ignore[index]
    assert engine.observe(door, 9.0) is None
    assert engine.observe(calm, 9.5) is not None, "a new frame is evaluated: the door closed"


def _link(
    engine: AlarmEngine,
    monotonic_s: float,
    *,
    connected: bool = False,
    refused: bool = False,
    reason: str | None = None,
    frame_age_s: float | None = None,
) -> list[tuple[str, str]]:
    events = engine.connection(
        connected=connected,
        refused=refused,
        reason=reason,
        frame_age_s=frame_age_s,
        stale_after_s=0.5,
        now_s=0.0,
        monotonic_s=monotonic_s,
    )
    return [(str(e["alarm"]["key"]), str(e["transition"])) for e in events]  # type: ignore[index]


def test_engine_connection_and_packet_loss() -> None:
    engine, _ = _engine()
    assert _link(engine, 100.0) == []  # not yet for connection_delay_s
    assert _link(engine, 102.0) == [("connection_lost", "activated")]
    assert _link(engine, 103.0, refused=True, reason="0x0109") == [
        ("forward_open_refused", "activated")
    ]
    assert _link(engine, 103.5) == []  # trying again: still refused until connected
    assert sorted(_link(engine, 104.0, connected=True, frame_age_s=0.01)) == [
        ("connection_lost", "cleared"),
        ("forward_open_refused", "cleared"),
    ]
    assert _link(engine, 105.0, connected=True, frame_age_s=0.6) == []  # stale, not yet long
    assert _link(engine, 107.0, connected=True, frame_age_s=2.6) == [
        ("connection_lost", "activated")
    ]
    assert engine.gaps(0, now_s=0.0, monotonic_s=0.0) == []
    assert engine.gaps(5, now_s=1.0, monotonic_s=30.0) == []
    assert not engine.packet_loss_high and engine.gaps_per_min == 5.0
    [event] = engine.gaps(20, now_s=2.0, monotonic_s=59.0)
    assert event["transition"] == "activated" and engine.packet_loss_high
    # A minute later with no new gap the rate falls back to 0.
    assert engine.gaps(20, now_s=3.0, monotonic_s=121.0)[0]["transition"] == "cleared"
    assert engine.gaps_per_min == 0.0


def test_engine_shelving_and_expiry() -> None:
    now = [1000.0]
    engine, published = _engine(clock=lambda: now[0])
    with pytest.raises(AlarmRefusedError):
        engine.shelve("left:packet_loss", "olivia", "flaky switch", 7200.0)  # over the maximum
    with pytest.raises(AlarmRefusedError):
        engine.shelve("left:packet_loss", "olivia", "  ", 60.0)
    alarm = engine.shelve("left:packet_loss", "olivia", "flaky switch", 60.0)
    assert alarm["shelved"] and alarm["shelved_until"] == 1060.0
    assert alarm["shelve_reason"] == "flaky switch" and alarm["shelved_by"] == "olivia"
    assert published[-1]["transition"] == "shelved"
    assert engine.expire_shelving(1059.0) == []
    [expired] = engine.expire_shelving(1060.0)
    assert expired["transition"] == "shelve_expired"
    assert expired["alarm"]["shelved"] is False  # type: ignore[index]


def test_engine_restores_persisted_states() -> None:
    engine, _ = _engine()
    estop = zero_frame()._replace(robot_state=0, emergency_stopped=True)
    engine.observe(estop, 1.0)
    record = engine.find("left:emergency_stop").status.to_json()
    again, _ = _engine()
    again.restore({"emergency_stop": record, "user.gone": record})
    assert again.find("left:emergency_stop").status.state is B
    assert again.observe(estop, 2.0) is None  # still there: not a new activation
    events = again.observe(zero_frame()._replace(robot_state=13), 3.0)
    assert events is not None and events[0]["alarm"]["state"] == "returned_unacknowledged"  # type: ignore[index]


# --------------------------------------------------------------------------- labels


def test_labels_are_the_spec_s_own() -> None:
    assert element_label("controlbox_do.2") == "DO 3"
    assert element_label("tool_do.0") == "Tool DO 1"
    assert element_label("analog_output.1") == "AO 1"
    assert element_label("analog_output_type.1") == "AO 1 type"
    assert element_label("bit_input_registers.40") == "Register 40"
    assert element_label("controlbox_do.16") is None
    assert element_label("emergency_stop") is None
    assert labels_of(["controlbox_do.2", "nonsense"]) == {"controlbox_do.2": "DO 3"}


def test_type_and_value_written_together_are_named_with_units() -> None:
    values = {"analog_output_type.1": 1, "analog_output.1": 5.0}
    assert write_summary(values, (0, 1)) == "AO 1 type = voltage, AO 1 = 5 V"
    assert write_summary({"analog_output.0": 12.5}, (0, 1)) == "AO 0 = 12.5 mA"
    assert (
        write_summary({"controlbox_do.2": True}, (0, 0), {"controlbox_do.2": "gripper close"})
        == "DO 3 (gripper close) = on"
    )


def test_csv_times_are_iso_8601_with_offset() -> None:
    text = iso8601(0.0)
    assert text[:4] in ("1970", "1969") and ("+" in text[19:] or "-" in text[19:])


# --------------------------------------------------------------------------- settings


def test_user_alarms_from_the_settings_file(tmp_path: Path) -> None:
    config = tmp_path / "cell.toml"
    config.write_text(
        """
[[robots]]
name = "left"
host = "127.0.0.1"

[[alarms]]
name = "gripper-pressure"
field = "analog_input"
index = 0
low = 4.5
high = 18.0
deadband = 0.2
on_delay_s = 1.0
off_delay_s = 2.0
priority = "high"
message = "Gripper pressure out of range"

[[alarms]]
name = "door"
robot = "left"
field = "controlbox_di"
index = 2
active_when = true
""",
        encoding="utf-8",
    )
    loaded = load_settings({}, {}, config)
    assert [a.name for a in loaded.alarm_limits.alarms] == ["gripper-pressure", "door"]
    assert (
        loaded.alarm_limits.alarms[0].deadband == 0.2
        and loaded.alarm_limits.alarms[1].robot == "left"
    )


@pytest.mark.parametrize(
    ("alarm", "words"),
    [
        ({"name": "x", "field": "nope", "index": 0, "high": 1}, "not a T→O field"),
        ({"name": "x", "field": "analog_input", "high": 1}, "give index"),
        ({"name": "x", "field": "analog_input", "index": 2, "high": 1}, "not in 0–1"),
        ({"name": "x", "field": "analog_input", "index": 0}, "high and/or low"),
        ({"name": "x", "field": "analog_input", "index": 0, "low": 5, "high": 4}, "below high"),
        ({"name": "x", "field": "controlbox_di", "index": 0, "high": 1}, "is a bit"),
        ({"name": "x", "field": "controller_version", "index": 0, "high": 1}, "record"),
        ({"name": "x", "robot": "right", "field": "servo_on", "active_when": False}, "right"),
    ],
)
def test_bad_user_alarms_are_refused_with_words(alarm: dict[str, object], words: str) -> None:
    with pytest.raises((SettingsError, ValueError), match=words):
        ServiceSettings.model_validate(
            {"robots": [{"name": "left", "host": "127.0.0.1"}], "alarms": [alarm]}
        )


# --------------------------------------------------------------------------- tag names


def test_tag_csv_round_trip_and_traps() -> None:
    tags = {"controlbox_do.2": "gripper close", "bit_input_registers.40": "part ready, left"}
    text = to_csv(tags)
    assert "controlbox_do.2,DO 3,gripper close" in text.splitlines()
    assert from_csv(text) == tags
    # By label only.
    assert from_csv("label,name\nDO 3,gripper close\n") == {"controlbox_do.2": "gripper close"}
    # A sheet edited with the label and the 0-based index off by one is refused with the line.
    with pytest.raises(TagError, match=r"line 2: controlbox_do\.3 is DO 4, not DO 3"):
        from_csv("key,label,name\ncontrolbox_do.3,DO 3,gripper close\n")
    with pytest.raises(TagError, match="not a taggable point"):
        check_tags({"analog_output_type.0": "x"})
    with pytest.raises(TagError, match="control characters"):
        check_tags({"controlbox_do.0": "a\nb"})
    assert "controlbox_do.0" in POINTS_BY_KEY and POINTS_BY_KEY["controlbox_do.0"].directions == (
        "T2O",
        "O2T",
    )


@settings(max_examples=200, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.floats(allow_nan=True, allow_infinity=True, width=32),
            st.booleans(),
            st.integers(min_value=0, max_value=20),
            st.floats(min_value=0.0, max_value=0.3),
        ),
        min_size=1,
        max_size=40,
    ),
    st.floats(min_value=0.0, max_value=3.0),
    st.floats(min_value=0.0, max_value=0.5),
)
def test_the_written_out_hot_paths_say_what_holds_says(
    steps: list[tuple[float, bool, int, float]], deadband: float, delay_s: float
) -> None:
    """Each condition's ``update`` has its ``holds`` written out for speed: run it beside the
    generic ``Condition.update`` (which calls ``holds``) on the same frames."""

    def limit() -> LimitCondition:
        return LimitCondition(
            "analog_input.1",
            "analog_input",
            1,
            high=10.0,
            low=-10.0,
            deadband=deadband,
            on_delay_s=delay_s,
            off_delay_s=delay_s,
        )

    def bit() -> BitCondition:
        return BitCondition("tool_di.3", "tool_di", 3, active_when=False, on_delay_s=delay_s)

    def state() -> StateCondition:
        return StateCondition(3, "INTERRUPTED", "safety_stopped")

    pairs: list[tuple[Condition, Condition]] = [
        (limit(), limit()),
        (bit(), bit()),
        (state(), state()),
    ]
    t = 0.0
    for value, bit_value, robot_state, dt in steps:
        t += dt
        frame = zero_frame()._replace(
            analog_input=(0.0, value),
            tool_di=(False, False, False, bit_value, False, False),
            robot_state=robot_state,
            safety_stopped=bit_value,
        )
        for fast, generic in pairs:
            assert fast.update(frame, t) == Condition.update(generic, frame, t)
            assert fast.active is generic.active


def test_a_failing_evaluation_stops_the_frame_alarms_not_the_frames() -> None:
    engine, _ = _engine()
    assert not engine.failed
    broken = zero_frame()._replace(robot_state=14, joint_motor_temperature=None)  # type: ignore[arg-type]
    assert engine.observe(broken, 1.0) is None
    assert engine.failed
    assert engine.observe(zero_frame(), 2.0) is None  # an e-stop frame: off, quietly
