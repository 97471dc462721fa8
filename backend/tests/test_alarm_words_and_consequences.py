"""Issue 24, the alarm engine's pure parts: an alarm that returns to normal names the robot's
state in words (every state of the layout, and one outside it); consequences are suppressed by
design (SAFE_OFF after an emergency stop's reset, a refused reconnection after a lost
connection), need no acknowledgement and name their cause; an alarm annunciated before its cause
came stays annunciated; the summary counts what a banner shows; events read in words."""

from __future__ import annotations

import re

import pytest

from cobot_hmi.codec import Frame, zero_frame
from cobot_hmi.layout import ROBOT_STATES, flag_fields
from cobot_hmi.service.alarms.engine import AlarmEngine
from cobot_hmi.service.alarms.state import AlarmState
from cobot_hmi.service.events.text import FrameWatcher, event_text, with_text

RUNNING = 14
ESTOP, SAFE_OFF, INTERRUPTED, STANDBY = 0, 2, 3, 13
STATE_ALARMS = {"emergency_stop": ESTOP, "protective_stop": INTERRUPTED, "safe_off": SAFE_OFF}
LABELS = {s.value: s.label for s in ROBOT_STATES}


def engine(**overrides: float) -> AlarmEngine:
    options: dict[str, float] = {
        "motor_temperature_c": 80.0,
        "motor_temperature_deadband_c": 2.0,
        "gap_rate_per_min": 10.0,
        "connection_delay_s": 2.0,
        "shelve_max_s": 3600.0,
        "consequence_window_s": 5.0,
    }
    options.update(overrides)
    return AlarmEngine("left", clock=lambda: 1000.0, **options)  # type: ignore[arg-type]


def frame(state: int, **flags: bool) -> Frame:
    return zero_frame()._replace(robot_state=state, **flags)  # type: ignore[arg-type]


def state(alarms: AlarmEngine, key: str) -> AlarmState:
    return alarms.find(f"left:{key}").status.state


def transitions(events: list[dict[str, object]] | None) -> dict[str, dict[str, object]]:
    return {e["alarm"]["key"]: e for e in events or []}  # type: ignore[index]


@pytest.mark.parametrize(
    ("key", "after"),
    [
        (key, after)
        for key, own in sorted(STATE_ALARMS.items())
        for after in [*(s.value for s in ROBOT_STATES), 42]
        if after != own  # its own state does not return it
    ],
)
def test_a_returned_alarm_names_the_state_in_words(key: str, after: int) -> None:
    own = STATE_ALARMS[key]
    alarms = engine()
    came = transitions(alarms.observe(frame(own), 1.0))[key]
    assert came["alarm"]["message"] == f"robot state {LABELS[own]}"  # type: ignore[index]
    went = transitions(alarms.observe(frame(after), 2.0))[key]
    assert went["transition"] == "cleared"
    message = went["alarm"]["message"]  # type: ignore[index]
    words = LABELS.get(after, f"state {after} (unknown)")
    assert message == f"robot state now {words}"
    # Never "robot state 2": a known state has no number in its words at all.
    if after in LABELS:
        assert not re.search(r"\d", str(message)), message


def test_the_emergency_stop_flag_is_said_in_words() -> None:
    alarms = engine()
    came = transitions(alarms.observe(frame(RUNNING, emergency_stopped=True), 1.0))
    message = came["emergency_stop"]["alarm"]["message"]  # type: ignore[index]
    assert message == "robot state Standalone running, Emergency stopped flag set"


def test_an_estop_then_its_reset_asks_for_one_acknowledgement() -> None:
    alarms = engine()
    alarms.observe(frame(RUNNING, servo_on=True), 0.5)
    alarms.observe(frame(ESTOP, emergency_stopped=True), 1.0)
    reset = transitions(alarms.observe(frame(SAFE_OFF), 2.0))
    assert reset["emergency_stop"]["transition"] == "cleared"
    safe_off = reset["safe_off"]
    assert safe_off["transition"] == "activated"
    assert safe_off["alarm"]["state"] == "suppressed"  # type: ignore[index]
    assert safe_off["alarm"]["suppressed_by"] == "left:emergency_stop"  # type: ignore[index]
    assert safe_off["alarm"]["suppressed_by_name"] == "Emergency stop"  # type: ignore[index]
    assert safe_off["alarm"]["active"] and safe_off["alarm"]["acknowledged"]  # type: ignore[index]
    # Nothing to acknowledge on the consequence; the one the operator acknowledges is the stop.
    alarm, changed = alarms.acknowledge("left:safe_off", "olivia", None)
    assert not changed and alarm["state"] == "suppressed"
    summary = alarms.summary()
    assert (summary["annunciated"], summary["unacknowledged"], summary["suppressed"]) == (1, 1, 1)
    top = summary["top"]
    assert isinstance(top, dict) and top["id"] == "left:emergency_stop"
    assert top["state"] == "returned_unacknowledged"
    # The consequence goes by itself: normal, nothing left behind.
    gone = transitions(alarms.observe(frame(STANDBY, servo_on=True), 2.5))
    assert gone["safe_off"]["transition"] == "cleared"
    assert state(alarms, "safe_off") is AlarmState.NORMAL
    assert [a["id"] for a in alarms.current()] == ["left:emergency_stop"]
    alarms.acknowledge("left:emergency_stop", "olivia", None)
    assert alarms.current() == []
    assert alarms.summary()["annunciated"] == 0


def test_a_protective_stop_s_reset_is_its_consequence_too() -> None:
    alarms = engine()
    alarms.observe(frame(INTERRUPTED, safety_stopped=True, servo_on=True), 1.0)
    reset = transitions(alarms.observe(frame(SAFE_OFF), 3.0))
    assert reset["safe_off"]["alarm"]["suppressed_by"] == "left:protective_stop"  # type: ignore[index]


def test_safe_off_long_after_a_stop_is_news() -> None:
    """Outside the window the robot going to SAFE_OFF is an error of its own: annunciated."""
    alarms = engine(consequence_window_s=5.0)
    alarms.observe(frame(ESTOP, emergency_stopped=True), 1.0)
    alarms.observe(frame(STANDBY, servo_on=True), 2.0)
    later = transitions(alarms.observe(frame(SAFE_OFF), 7.5))
    assert later["safe_off"]["alarm"]["state"] == "active_unacknowledged"  # type: ignore[index]
    assert later["safe_off"]["alarm"]["suppressed_by"] is None  # type: ignore[index]
    assert alarms.summary()["annunciated"] == 2


def test_a_protective_stop_just_after_an_estop_s_reset_is_news() -> None:
    alarms = engine()
    alarms.observe(frame(ESTOP, emergency_stopped=True), 1.0)
    alarms.observe(frame(SAFE_OFF), 2.0)
    alarms.observe(frame(STANDBY, servo_on=True), 2.5)
    stop = transitions(alarms.observe(frame(INTERRUPTED, safety_stopped=True), 3.0))
    assert stop["protective_stop"]["alarm"]["state"] == "active_unacknowledged"  # type: ignore[index]


def test_an_estop_s_stop_flags_are_one_alarm() -> None:
    """A robot that sets SS with ES: the protective stop is the emergency stop's consequence."""
    alarms = engine()
    came = transitions(alarms.observe(frame(ESTOP, emergency_stopped=True, safety_stopped=True), 1))
    assert came["emergency_stop"]["alarm"]["state"] == "active_unacknowledged"  # type: ignore[index]
    assert came["protective_stop"]["alarm"]["state"] == "suppressed"  # type: ignore[index]
    # SAFE_OFF after the reset is named after the stop the operator saw, not the suppressed one.
    reset = transitions(alarms.observe(frame(SAFE_OFF), 2.0))
    assert reset["safe_off"]["alarm"]["suppressed_by"] == "left:emergency_stop"  # type: ignore[index]


def link(
    alarms: AlarmEngine, t: float, *, connected: bool = False, refused: bool = False
) -> dict[str, dict[str, object]]:
    return transitions(
        alarms.connection(
            connected=connected,
            refused=refused,
            reason="0x0315" if refused else None,
            frame_age_s=0.01 if connected else None,
            stale_after_s=0.5,
            now_s=t,
            monotonic_s=t,
        )
    )


def test_link_alarms_group_under_the_first() -> None:
    alarms = engine()
    refused = link(alarms, 100.0, refused=True)
    assert refused["forward_open_refused"]["alarm"]["state"] == "active_unacknowledged"  # type: ignore[index]
    lost = link(alarms, 102.5, refused=True)["connection_lost"]
    assert lost["alarm"]["state"] == "suppressed"  # type: ignore[index]
    assert lost["alarm"]["suppressed_by"] == "left:forward_open_refused"  # type: ignore[index]
    assert alarms.summary()["annunciated"] == 1
    # Connected at last: both go; the gaps right after are the refusal's, the root's.
    assert set(link(alarms, 110.0, connected=True)) == {"forward_open_refused", "connection_lost"}
    alarms.gaps(0, now_s=110.5, monotonic_s=110.5)
    [loss] = alarms.gaps(40, now_s=111.0, monotonic_s=111.0)
    assert loss["alarm"]["suppressed_by"] == "left:forward_open_refused"  # type: ignore[index]


def test_an_alarm_annunciated_before_its_cause_stays_annunciated() -> None:
    alarms = engine()
    alarms.gaps(0, now_s=1.0, monotonic_s=0.0)
    [loss] = alarms.gaps(50, now_s=2.0, monotonic_s=10.0)
    assert loss["alarm"]["state"] == "active_unacknowledged"  # type: ignore[index]
    link(alarms, 100.0)
    lost = link(alarms, 102.5)["connection_lost"]
    assert lost["alarm"]["state"] == "active_unacknowledged"  # type: ignore[index]
    assert state(alarms, "packet_loss") is AlarmState.ACTIVE_UNACKNOWLEDGED
    summary = alarms.summary()
    by_priority = summary["by_priority"]
    assert isinstance(by_priority, dict)
    assert by_priority["high"] == {"annunciated": 1, "active": 1, "unacknowledged": 1}
    assert by_priority["medium"] == {"annunciated": 1, "active": 1, "unacknowledged": 1}
    top = summary["top"]
    assert isinstance(top, dict) and top["key"] == "connection_lost"  # high before medium


def test_a_restart_keeps_the_suppression() -> None:
    alarms = engine()
    alarms.observe(frame(ESTOP, emergency_stopped=True), 1.0)
    alarms.observe(frame(SAFE_OFF), 2.0)
    records = {key: a.status.to_json() for key, a in alarms.alarms.items()}
    again = engine()
    again.restore(records)
    assert state(again, "safe_off") is AlarmState.SUPPRESSED
    assert again.snapshot_of("safe_off")["suppressed_by"] == "left:emergency_stop"
    assert again.observe(frame(SAFE_OFF), 3.0) is None  # still there: nothing new


@pytest.mark.parametrize("flag", [f.name for f in flag_fields()])
@pytest.mark.parametrize("value", [True, False])
def test_flag_events_read_in_words(flag: str, value: bool) -> None:
    watcher = FrameWatcher()
    watcher.observe(frame(RUNNING, **{flag: not value}), 1.0)
    [event] = watcher.observe(frame(RUNNING, **{flag: value}), 2.0)
    text = with_text(event)["text"]
    label = next(f.description for f in flag_fields() if f.name == flag)
    assert text == f"{label} flag {'set' if value else 'cleared'}"
    assert " on on" not in str(text) and " off off" not in str(text)


def test_every_event_kind_reads_in_words() -> None:
    assert event_text({"kind": "robot_state", "from": RUNNING, "to": ESTOP}) == (
        "Robot state Emergency stop (was Standalone running)"
    )
    assert event_text({"kind": "robot_state", "from": None, "to": STANDBY}) == (
        "Robot state Standalone standby (first frame)"
    )
    assert event_text({"kind": "connection", "state": "lost", "reason": "no frame"}) == (
        "Connection lost: no frame"
    )
    write = {"kind": "write", "user": "olivia", "fields": ["controlbox_do.2"], "outcome": "invalid"}
    assert event_text(write) == "Write by olivia: DO 3 → invalid"
    assert event_text({**write, "summary": "DO 3 = on", "outcome": "confirmed"}) == (
        "Write by olivia: DO 3 = on → confirmed"
    )
    assert event_text({"kind": "control", "holder": {"user": "olivia"}}) == (
        "Control held by olivia"
    )
    assert event_text({"kind": "control", "holder": None, "reason": "connection lost"}) == (
        "Control free, nobody holds it: connection lost"
    )
    assert event_text({"kind": "recording", "state": "paused", "reason": "disk full"}) == (
        "Recording paused: disk full"
    )
    assert event_text(
        {"kind": "session", "user": "olivia", "reason": "logged out", "streams_closed": 2}
    ) == ("Session of olivia ended (logged out): 2 streams closed")
    alarms = engine()
    [came] = alarms.observe(frame(ESTOP, emergency_stopped=True), 1.0) or []
    assert event_text(came) == (
        "Emergency stop activated: robot state Emergency stop, Emergency stopped flag set"
    )
    reset = transitions(alarms.observe(frame(SAFE_OFF), 2.0))
    assert event_text(reset["safe_off"]) == (
        "Servo off after an error (SAFE_OFF) activated, suppressed by design (a consequence of "
        "Emergency stop): robot state Safe off (servo off)"
    )
    assert event_text(reset["emergency_stop"]) == (
        "Emergency stop returned to normal: robot state now Safe off (servo off)"
    )
