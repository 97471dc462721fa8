"""Layer: service. Every robot's health in the running service: one ``RobotHealth`` per robot,
one thread that feeds them all, their state in the database, their verdicts as advisory alarms
and ``health`` events (docs/health.md "In the service").

- Frames: each robot's ``RobotHealth`` is a consumer of its frames on the health thread (never
  on the cyclic path; a queue that overflows drops and counts, ``robots.frame_notifier``).
- Cycles: the cycle meter announces each measured cycle as a ``cycle`` event; ``Health`` is a
  consumer of the event bus and hands each to its robot's ``RobotHealth``, which ends it in the
  engine once the engine has every frame of it.
- Verdicts: every ``health_report_s`` the thread computes each robot's report and hands it to
  the web loop, which raises or clears the robot's advisory alarms (``health.1`` … ``health.6``,
  priority advisory, through its alarm engine: acknowledged and shelved as any other) and
  publishes a ``health`` event when a verdict or a joint's life used (to 0.1 %) changed.
- Durability (``health.store``): restored at start, saved every ``health_save_s`` and at stop;
  a snapshot of the figures every ``health_snapshot_s`` for the trends.
- Each robot's latest ``health`` event (``Health.latest``, a ``LatestHealth``) is read by the
  OPC UA server from its own thread: the web loop never changes what a reader may hold, it
  replaces the whole read-only snapshot (``LatestHealth.publish``).
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import functools
import logging
import threading
import time
from collections.abc import Coroutine, Iterator, Mapping, Sequence
from pathlib import Path
from types import MappingProxyType
from typing import Any, Final

from cobot_hmi.health import HealthEngine
from cobot_hmi.health.baseline import Baseline
from cobot_hmi.service.alarms.engine import AlarmEngine
from cobot_hmi.service.errors import ApiError
from cobot_hmi.service.events.text import Event
from cobot_hmi.service.extensions import MetricFamily
from cobot_hmi.service.health.answers import baseline_answer, baselines_answer, report_answer
from cobot_hmi.service.health.health_service_settings import HealthServiceSettings
from cobot_hmi.service.health.monitor import RobotHealth, arm_of, worst_verdict
from cobot_hmi.service.health.period import PeriodCycle, PeriodRequest, learn_period
from cobot_hmi.service.health.store import HealthStore, Snapshot, snapshot_of
from cobot_hmi.service.robots.robot import RobotRuntime
from cobot_hmi.service.storage.store import Store

log = logging.getLogger(__name__)

ALARM_PREFIX: Final = "health."
LIFE_STEP_PERCENT: Final = 0.1
"""A joint's life used is announced again once it changed by this much (``health`` events)."""


def health_event(report: Mapping[str, object], now_s: float) -> Event:
    """The ``health`` event of a report: the robot's verdict and each joint's verdict, reason
    and life used (docs/api.md "Events")."""
    joints = report["joints"]
    assert isinstance(joints, list)
    verdict = worst_verdict(joints)
    return {
        "kind": "health",
        "time": now_s,
        "verdict": verdict,
        "maintenance_due": verdict != "ok",
        "joints": [
            {
                "joint": j["joint"],
                "verdict": j["verdict"],
                "reason": j["reason"],
                "life_used_percent": j["life_used_percent"],
            }
            for j in joints
        ],
    }


def frozen_event(event: Event) -> Mapping[str, object]:
    """A ``health`` event nobody can change: read-only, its joints a tuple of read-only ones."""
    joints = event.get("joints")
    entries = joints if isinstance(joints, list) else []
    return MappingProxyType(
        {**event, "joints": tuple(MappingProxyType(dict(entry)) for entry in entries)}
    )


class LatestHealth(Mapping[str, Mapping[str, object]]):
    """Each robot's last ``health`` event, read from other threads (the OPC UA server's) while
    the web loop publishes, thread-safe by construction: a snapshot (a read-only mapping of
    frozen events) is never changed once made; each new event replaces it whole, by one
    reference store, so a reader sees the previous snapshot or the next, never one changing."""

    def __init__(self) -> None:
        self._snapshot: Mapping[str, Mapping[str, object]] = MappingProxyType({})

    def __getitem__(self, name: str) -> Mapping[str, object]:
        return self._snapshot[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._snapshot)

    def __len__(self) -> int:
        return len(self._snapshot)

    def publish(self, name: str, event: Event) -> None:
        """The robot's new event (on the web loop, the one writer)."""
        self._snapshot = MappingProxyType({**self._snapshot, name: frozen_event(event)})


def advise(alarms: AlarmEngine, report: Mapping[str, object], now_s: float) -> list[Event]:
    """Each joint's advisory alarm (``health.N``) from a report: active while its verdict is
    watch or act, its reason the alarm's message; the alarm events of what changed."""
    joints = report["joints"]
    assert isinstance(joints, list)
    events: list[Event] = []
    for joint in joints:
        events += alarms.raised(
            f"{ALARM_PREFIX}{joint['joint']}",
            active=joint["verdict"] != "ok",
            message=str(joint["reason"]),
            now_s=now_s,
        )
    return events


def _event_key(event: Event) -> tuple[object, ...]:
    joints = event["joints"]
    assert isinstance(joints, list)
    return tuple(
        (j["verdict"], round(float(j["life_used_percent"] or 0.0) / LIFE_STEP_PERCENT))
        for j in joints
    )


class Health:
    """The cell's robot health (see the module docstring): ``open`` after the store opened,
    ``start`` before the first frame, ``stop`` after the frames stopped."""

    name: Final = "health"

    def __init__(
        self, settings: HealthServiceSettings, robots: Mapping[str, RobotRuntime], store: Store
    ) -> None:
        self.settings = settings
        self.robots = robots
        self.store = HealthStore(store)
        self.monitors: dict[str, RobotHealth] = {}
        self.latest = LatestHealth()
        """Each robot's last ``health`` event (what its doors show now; other threads read it)."""
        self._announced: dict[str, tuple[object, ...]] = {}
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stopping = threading.Event()
        self._thread: threading.Thread | None = None
        self._saving: set[asyncio.Future[None]] = set()
        self.failures = 0
        self.cpu_seconds = 0.0
        """CPU time of the health thread (what health costs the cell, ``/metrics``)."""

    @property
    def enabled(self) -> bool:
        return self.settings.health_enabled

    # ------------------------------------------------------------ lifecycle (web loop)

    async def open(self) -> None:
        """Each robot's engine restored from its saved state (or new)."""
        if not self.enabled:
            return
        for name, robot in self.robots.items():
            document = await self.store.load(name)
            if document is not None:
                engine = HealthEngine.from_document(document)
            else:
                engine = HealthEngine(arm_of(robot, self.settings.health_arm))
            self.monitors[name] = RobotHealth(robot, engine, self.settings.health_queue_frames)

    def start(self) -> None:
        """On the web loop, before the first frame: registered, the thread running."""
        if not self.enabled:
            return
        self._loop = asyncio.get_running_loop()
        for name, monitor in self.monitors.items():
            monitor.registration = self.robots[name].frames.add(monitor)
        self._thread = threading.Thread(target=self._run, name="health", daemon=True)
        self._thread.start()

    async def stop(self) -> None:
        """After the frames stopped: the last frames and cycles fed, every state saved."""
        if self._thread is None:
            return
        self._stopping.set()
        await asyncio.to_thread(self._thread.join)
        self._thread = None
        for name, monitor in self.monitors.items():
            await asyncio.to_thread(monitor.step)
            if monitor.registration is not None:
                self.robots[name].frames.remove(monitor.registration)
                monitor.registration = None
        if self._saving:
            await asyncio.gather(*self._saving, return_exceptions=True)
        for name, monitor in self.monitors.items():
            await self.save(name, monitor)

    async def save(self, name: str, monitor: RobotHealth) -> None:
        document, baselines = await asyncio.to_thread(monitor.document)
        await self.store.save(name, time.time(), document, baselines)

    # ------------------------------------------------------------ events (web loop)

    def on_events(self, events: Sequence[Event]) -> None:
        """The cycle meter's cycles to their robot's engine."""
        for event in events:
            if event.get("kind") != "cycle":
                continue
            monitor = self.monitors.get(str(event.get("robot")))
            start, end = event.get("time"), event.get("end")
            if monitor is not None and isinstance(start, float) and isinstance(end, float):
                monitor.add_cycle(start, end, event.get("interruption") is not None)

    def apply(self, name: str, report: dict[str, object], now_s: float) -> None:
        """On the web loop: a robot's report to its advisory alarms and its ``health`` event."""
        robot = self.robots[name]
        robot.publish_events(advise(robot.alarms, report, now_s))
        event = health_event(report, now_s)
        key = _event_key(event)
        if self._announced.get(name) != key:
            self._announced[name] = key
            self.latest.publish(name, event)
            robot.publish_event(dict(event))

    # ------------------------------------------------------------ the health thread

    def _run(self) -> None:
        s = self.settings
        now = time.monotonic()
        next_report, next_save, next_snapshot = now + s.health_report_s, now + s.health_save_s, now
        while not self._stopping.wait(s.health_refresh_s):
            cpu_start_s = time.thread_time()
            now = time.monotonic()
            report_due, save_due = now >= next_report, now >= next_save
            snapshot_due = now >= next_snapshot
            for name, monitor in self.monitors.items():
                try:
                    self._turn(name, monitor, report_due, save_due, snapshot_due)
                except Exception:  # one robot's failure must not end every robot's health
                    self.failures += 1
                    log.exception("%s: health failed", name)
            if report_due:
                next_report = now + s.health_report_s
            if save_due:
                next_save = now + s.health_save_s
            if snapshot_due:
                next_snapshot = now + s.health_snapshot_s
            self.cpu_seconds += time.thread_time() - cpu_start_s

    def _turn(
        self, name: str, monitor: RobotHealth, report_due: bool, save_due: bool, snapshot: bool
    ) -> None:
        monitor.adopt_arm(self.settings.health_arm)
        monitor.step()
        loop = self._loop
        if loop is None:
            return
        if report_due or snapshot:
            now_s = time.time()
            report = monitor.report(now_s)
            if report_due:
                with contextlib.suppress(RuntimeError):  # the loop closed during shutdown
                    loop.call_soon_threadsafe(self.apply, name, report, now_s)
            if snapshot:
                joints = report["joints"]
                assert isinstance(joints, list)
                worst = worst_verdict(joints)
                self._submit(self.store.add_snapshot(name, snapshot_of(report, worst)))
        if save_due:
            self._submit(self.save(name, monitor))

    def _submit(self, coroutine: Coroutine[Any, Any, None]) -> None:
        """Run a store coroutine on the web loop (from the health thread), tracked so ``stop``
        waits for it."""
        loop = self._loop
        assert loop is not None
        try:
            future = asyncio.run_coroutine_threadsafe(coroutine, loop)
            loop.call_soon_threadsafe(self._track, future)
        except RuntimeError:  # the loop closed during shutdown
            coroutine.close()

    def _track(self, future: concurrent.futures.Future[None]) -> None:
        wrapped = asyncio.wrap_future(future)
        self._saving.add(wrapped)
        wrapped.add_done_callback(self._done)

    def _done(self, future: asyncio.Future[None]) -> None:
        self._saving.discard(future)
        if not future.cancelled() and future.exception() is not None:
            self.failures += 1
            log.error("health: saving failed: %s", future.exception())

    def metric_families(self) -> list[MetricFamily]:
        """Health's counters for ``/metrics`` (the verdicts themselves are the REST answer's
        and the doors')."""
        monitors = list(self.monitors.items())

        def per_robot(value: str) -> list[tuple[dict[str, str], float]]:
            return [({"robot": name}, float(getattr(m, value))) for name, m in monitors]

        return [
            ("health_frames_fed_total", "counter", "frames fed to the health engine",
             per_robot("frames_fed")),
            ("health_cycles_fed_total", "counter", "measured cycles ended in the engine",
             per_robot("cycles_fed")),
            ("health_cycles_refused_total", "counter",
             "measured cycles the engine could not take", per_robot("cycles_refused")),
            ("health_failures_total", "counter", "health turns or saves that failed (logged)",
             [({}, float(self.failures))]),
            ("health_cpu_seconds_total", "counter", "CPU time of the health thread",
             [({}, self.cpu_seconds)]),
        ]  # fmt: skip

    # ------------------------------------------------------------ the routes (web loop)

    def monitor(self, name: str) -> RobotHealth:
        """The robot's health; ``ApiError`` 409 while health is off."""
        monitor = self.monitors.get(name)
        if monitor is None:
            raise ApiError(409, "robot health is off (health_enabled)")
        return monitor

    async def answer(self, name: str) -> dict[str, object]:
        """``models_health.HealthReport`` of the robot now."""
        monitor = self.monitor(name)
        report = await asyncio.to_thread(monitor.report, time.time())
        registration = monitor.registration
        dropped = registration.dropped if registration is not None else 0
        return report_answer(name, report, dropped)

    async def baselines(self, name: str) -> list[dict[str, object]]:
        """Every baseline of the robot: the stored ones and the engine's (newer), oldest
        first."""
        monitor = self.monitor(name)
        stored = await self.store.baselines(name)
        records, active, learning, learned = await asyncio.to_thread(monitor.baselines)
        by_id = {info["id"]: info for info in stored} | {info["id"]: info for info in records}
        ordered = [by_id[key] for key in sorted(by_id, key=lambda k: int(str(k)))]
        return baselines_answer(ordered, active, learning, learned)

    async def begin_baseline(
        self, name: str, reason: str, by: str, cycles: int
    ) -> dict[str, object]:
        """Learn a new baseline from the next ``cycles`` whole cycles; saved at once. ``ApiError``
        409 while health is off or the robot has no cycles (no ``cycle_trigger``)."""
        monitor = self.monitor(name)
        if self.robots[name].settings.cycle_trigger_parsed is None:
            raise ApiError(
                409,
                f"robot {name} has no cycle_trigger: a baseline is learned from its measured "
                'cycles (docs/operations.md, "Cycle timing")',
            )
        info = await asyncio.to_thread(monitor.begin_baseline, reason, by, time.time(), cycles)
        await self.save(name, monitor)
        return baseline_answer(info, active=False, learning=True, cycles=0)

    async def learn_period(
        self,
        name: str,
        request: PeriodRequest,
        history_root: Path,
        cycles: Sequence[PeriodCycle],
    ) -> dict[str, object]:
        """Learn a baseline from a recorded period (``period.learn_period``) off the web loop,
        adopt it as the active one, save. ``ApiError`` 409 while health is off, a baseline is
        being learned, or the period holds no recording or too few cycles."""
        monitor = self.monitor(name)
        if monitor.engine.learning is not None:
            raise ApiError(409, "a baseline is being learned from the next cycles: wait for it")
        with monitor.lock:
            arm, settings = monitor.engine.arm, monitor.engine.settings
        try:
            learned = await asyncio.to_thread(
                functools.partial(
                    learn_period,
                    arm,
                    settings,
                    history_root=history_root,
                    robot=name,
                    cycles=cycles,
                    request=request,
                )
            )
            record = await asyncio.to_thread(self._adopt, monitor, learned, time.time())
        except ValueError as error:  # PeriodError, or a baseline began learning meanwhile
            raise ApiError(409, str(error)) from None
        await self.save(name, monitor)
        return baseline_answer(record, active=True, learning=False)

    @staticmethod
    def _adopt(monitor: RobotHealth, learned: Baseline, now_s: float) -> dict[str, object]:
        with monitor.lock:
            if learned.info["arm"] != monitor.engine.arm.name:
                raise ValueError("the robot's health engine changed meanwhile: ask again")
            return dict(monitor.engine.adopt_learned(learned, now_s))

    async def trend(
        self, name: str, since: float | None, until: float | None, limit: int
    ) -> list[Snapshot]:
        self.monitor(name)
        return await self.store.snapshots(name, since, until, limit)
