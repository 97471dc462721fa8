"""A robot's parts built alone, as ``RobotRuntime`` composes them: the connection watch (its
events, counters, connection alarms and readiness, over a real link that was never started and a
real alarm engine) and the identity reader (against the emulator's ListIdentity, and a robot that
does not answer)."""

from __future__ import annotations

import socket

from cobot_hmi.emulator.target import Target
from cobot_hmi.scanner.originator import ConnectionState
from cobot_hmi.scanner.t2o_pace import SlowTarget
from cobot_hmi.service.alarms.engine import AlarmEngine
from cobot_hmi.service.events.text import Event
from cobot_hmi.service.robots.connection_watch import ConnectionWatch
from cobot_hmi.service.robots.frame_notifier import FrameNotifier
from cobot_hmi.service.robots.identity import IdentityReader, RobotIdentity
from cobot_hmi.service.robots.link import CyclicLoop, RobotLink
from cobot_hmi.service.robots.robot_settings import RobotSettings


class _Watched:
    """A watch over a link of its own, with what it published and called."""

    def __init__(self) -> None:
        self.events: list[Event] = []
        self.connected = 0
        self.down: list[ConnectionState] = []
        settings = RobotSettings(name="r", host="127.0.0.1")
        self.cyclic = CyclicLoop("127.0.0.1", 0)
        self.link = RobotLink(
            "r",
            settings.originator_settings("127.0.0.1", 0),
            self.cyclic,
            on_frame=FrameNotifier("r").publish,
            # Late-bound, as the robot binds it: the watch is made below, over this link.
            on_state=lambda state, reason: self.watch.on_state(state, reason),  # noqa: PLW0108
        )
        self.alarms = AlarmEngine(
            "r",
            motor_temperature_c=80.0,
            motor_temperature_deadband_c=2.0,
            gap_rate_per_min=10.0,
            connection_delay_s=0.0,
            shelve_max_s=3600.0,
        )
        self.watch = ConnectionWatch(
            "r",
            self.link,
            FrameNotifier("r"),
            self.alarms,
            publish_event=self.events.append,
            publish_events=self.events.extend,
            stale_after_s=0.5,
            on_connected=self._connected,
            on_down=self.down.append,
        )

    def _connected(self) -> None:
        self.connected += 1

    def of(self, kind: str) -> list[Event]:
        return [e for e in self.events if e.get("kind") == kind]


def test_the_connection_watch_counts_and_says_each_change() -> None:
    w = _Watched()
    assert (w.watch.connects, w.watch.losses) == (0, 0)
    assert w.watch.down_since is not None  # down until first connected
    w.watch.on_state(ConnectionState.CONNECTED, None)
    assert (w.watch.connects, w.connected) == (1, 1)
    assert w.watch.down_since is None
    assert w.watch.down_for_s() is None
    w.watch.on_state(ConnectionState.LOST, "no T→O for 40 ms")
    w.watch.on_state(ConnectionState.REFUSED, "0x0100 connection in use")
    assert (w.watch.connects, w.watch.losses) == (1, 1)  # lost once, then refused while down
    assert w.down == [ConnectionState.LOST, ConnectionState.REFUSED]
    assert w.watch.down_since is not None and (w.watch.down_for_s() or 0.0) >= 0.0
    said = [(e["state"], e["reason"]) for e in w.of("connection")]
    assert said == [
        ("connected", None),
        ("lost", "no T→O for 40 ms"),
        ("refused", "0x0100 connection in use"),
    ]


def test_the_connection_watch_raises_the_connection_alarm_and_says_why_not_ready() -> None:
    w = _Watched()
    assert w.watch.ready() == (False, "idle")  # the link never started
    w.link._thread_died("boom")  # the link reports the loss to the watch itself
    ready, reason = w.watch.ready()
    assert not ready and reason == "lost: the cyclic I/O thread died: boom"
    alarms = w.of("alarm")
    assert alarms and all(e["robot"] == "r" for e in alarms)
    assert w.alarms.alarms["connection_lost"].status.state.active
    before = len(w.events)
    w.watch.alarm_tick()  # nothing changed: the tick says nothing new
    assert len(w.events) == before


def test_the_connection_watch_says_a_slow_target_once_and_its_recovery() -> None:
    w = _Watched()
    w.watch.on_slow_target(None)  # never slow: nothing to say
    slow = SlowTarget(granted_ms=10.0, sends_every_ms=20.0)
    w.watch.on_slow_target(slow)
    w.watch.on_slow_target(None)
    reasons = [e["reason"] for e in w.of("connection")]
    assert reasons == [slow.words("robot"), slow.kept_words("robot")]


async def test_the_identity_reader_reads_the_robots_identity(target: Target) -> None:
    host, port = target.settings.host, target.tcp_port
    reader = IdentityReader("r", host, port)
    assert reader.identity is None
    await reader.read()
    assert reader.identity == RobotIdentity.from_info(target.identity)


async def test_a_robot_that_does_not_answer_keeps_its_identity(robot_host: str) -> None:
    with socket.socket() as closed:  # a port nobody listens on
        closed.bind((robot_host, 0))
        port = closed.getsockname()[1]
    reader = IdentityReader("r", robot_host, port, timeout_s=2.0)
    await reader.read()
    assert reader.identity is None
