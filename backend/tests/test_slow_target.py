"""A target slower than its grant (issue 27, part 2): the emulator's ``t2o_interval_factor``
fault grants the RPI asked for and sends T→O every factor × RPI (5 here, so the verdict "median
above 1.5 × API" has a huge margin whatever the load). The scanner reports it once, in words, and
once more when the target keeps its grant again: to ``on_slow_target``, in its stats, on
``scan``'s stderr and in its summary, and in the service's connection status and events.

Every wait is on a condition; no assertion is on a time.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import signal
import sys
from collections.abc import AsyncIterator, Awaitable, Callable
from pathlib import Path
from typing import TypeVar

import pytest

from cobot_hmi.codec import command_from_json, encode_command
from cobot_hmi.emulator.faults import TargetFaults
from cobot_hmi.emulator.target import Target
from cobot_hmi.scanner.originator import ConnectionState, Originator, OriginatorSettings
from cobot_hmi.scanner.t2o_pace import WINDOW_S, PaceWatch, SlowTarget
from cobot_hmi.service.api import models
from emulator_harness import running_emulator
from service_support import VIEWER, emulator, running_service, service_settings
from service_support import eventually as _eventually

_T = TypeVar("_T")


async def eventually(check: Callable[[], object]) -> None:
    await _eventually(check, DEADLINE_S)


DEADLINE_S = 120.0
"""A generous functional deadline, never a timing figure (the slow target's verdicts come
from windows of frames, which a loaded machine delivers late)."""
FACTOR = 5.0
RPI_US = 10_000
SLOW_FRAMES = round(4 * WINDOW_S * 1e6 / (RPI_US * FACTOR))
"""Frames of four verdicts' windows from the slow target."""
KEPT_FRAMES = round(4 * WINDOW_S * 1e6 / RPI_US)
"""Frames of four verdicts' windows once it keeps its grant."""


# --------------------------------------------------------------------------- the measure


def _feed(
    watch: PaceWatch, start_s: float, count: int, every_s: float, seq: int, *, step: int = 1
) -> tuple[list[SlowTarget | None], float, int]:
    """``count`` packets every ``every_s`` from ``start_s``, the sequence rising by ``step``;
    the reports made, the next time and sequence number."""
    reports: list[SlowTarget | None] = []
    at = start_s
    for _ in range(count):
        if watch.packet(at, seq & 0xFFFFFFFF):
            reports.append(watch.slow)
        at += every_s
        seq += step
    return reports, at, seq


def test_slow_reported_once_then_kept_once() -> None:
    watch = PaceWatch()
    watch.restart(2_000)
    reports, at, seq = _feed(watch, 100.0, 100, 0.002, 1)
    assert reports == [] and watch.slow is None, "a target keeping its grant"
    reports, at, seq = _feed(watch, at, 300, 0.010, seq)
    assert len(reports) == 1 and reports[0] is not None
    assert reports[0].granted_ms == 2.0
    assert reports[0].sends_every_ms == pytest.approx(10.0)
    assert reports[0].words("robot") == "the robot grants 2 ms but sends every 10 ms"
    reports, at, seq = _feed(watch, at, 2000, 0.002, seq)
    assert reports == [None], "cleared once"
    assert watch.found is not None
    assert watch.found.kept_words("robot") == "the robot keeps its 2 ms grant again"


def test_lost_packets_and_a_wrapping_sequence_are_not_slowness() -> None:
    """Half the packets lost (the sequence number jumps by 2 each time): on time all the same."""
    watch = PaceWatch()
    watch.restart(2_000)
    reports, _, _ = _feed(watch, 5.0, 2000, 0.004, 0xFFFFFF00, step=2)
    assert reports == [] and watch.slow is None


def test_a_verdict_needs_a_second_and_between_the_thresholds_nothing_changes() -> None:
    watch = PaceWatch()
    watch.restart(100_000)  # 100 ms: a second holds 10 intervals
    reports, at, seq = _feed(watch, 0.0, int(WINDOW_S / 0.5), 0.5, 1)
    assert reports == [], "fewer intervals than a verdict needs"
    reports, at, seq = _feed(watch, at, 20, 0.5, seq)
    assert reports == [SlowTarget(100.0, 500.0)]
    reports, at, seq = _feed(watch, at, 100, 0.14, seq)  # 1.4 × API: not kept yet
    assert reports == [] and watch.slow is not None
    watch.restart(100_000)
    assert watch.slow is None and watch.found is None, "a new connection: nothing reported"


# --------------------------------------------------------------------------- the originator


async def test_originator_reports_a_slow_emulator_once_and_its_recovery_once(
    robot_host: str, plc_host: str
) -> None:
    """The fault through the emulator's control API, as a tester would set it."""
    async with running_emulator(robot_host, plc_host) as emu:
        for bad in (0.5, 101, "5"):
            await emu.post("/faults", {"t2o_interval_factor": bad}, expect=422)
        answer = await emu.post("/faults", {"t2o_interval_factor": FACTOR})
        assert answer["faults"]["t2o_interval_factor"] == FACTOR  # type: ignore[index]
        reports: list[SlowTarget | None] = []
        originator = Originator(
            OriginatorSettings(
                robot_host=robot_host,
                tcp_port=emu.target.tcp_port,
                local_host=plc_host,
                rpi_us=RPI_US,
                # RPI × 512 (5.12 s): a loaded machine's stalls must not time the connection out
                # (a new connection is judged anew and reported again: at load 15 it did).
                timeout_multiplier=7,
            ),
            on_slow_target=reports.append,
        )
        emu.originator = originator  # stopped by the harness
        await originator.start()
        assert await originator.wait_connected(DEADLINE_S)
        await eventually(lambda: reports)
        slow = reports[0]
        assert slow is not None and slow.granted_ms == RPI_US / 1e3
        assert slow.sends_every_ms > 1.5 * slow.granted_ms
        assert originator.stats().slow_target == slow
        # Many more windows of the slow target: still one report.
        frames = originator.frames
        await eventually(lambda: originator.frames >= frames + SLOW_FRAMES)
        assert reports == [slow]
        stats = originator.stats()
        assert stats.gaps == 0, "a slow target loses no packet"
        assert stats.late > 0, "each of its frames is late"

        await emu.post("/faults/clear")
        await eventually(lambda: len(reports) == 2)
        assert reports[1] is None
        assert originator.stats().slow_target is None
        frames = originator.frames
        await eventually(lambda: originator.frames >= frames + KEPT_FRAMES)
        assert reports == [slow, None], "cleared once"
        status = (await emu.api.get("/status")).json()
        assert status["faults"]["t2o_interval_factor"] == 1.0


# --------------------------------------------------------------------------- scan


class _Scan:
    """``cobot-hmi scan`` in a subprocess, its stdout and stderr lines read as they come."""

    def __init__(self, process: asyncio.subprocess.Process) -> None:
        self.process = process
        self.out: list[str] = []
        self.err: list[str] = []
        assert process.stdout is not None and process.stderr is not None
        self._readers = [
            asyncio.create_task(self._read(process.stdout, self.out)),
            asyncio.create_task(self._read(process.stderr, self.err)),
        ]

    @staticmethod
    async def _read(stream: asyncio.StreamReader, lines: list[str]) -> None:
        while line := await stream.readline():
            lines.append(line.decode().rstrip("\n"))

    def said(self, words: str) -> list[str]:
        return [line for line in self.err if words in line]

    async def interrupt(self) -> int:
        self.process.send_signal(signal.SIGINT)
        code = await asyncio.wait_for(self.process.wait(), DEADLINE_S)
        await asyncio.gather(*self._readers)
        return code

    async def kill(self) -> None:
        if self.process.returncode is None:
            self.process.kill()
            await self.process.wait()
        await asyncio.gather(*self._readers, return_exceptions=True)


@contextlib.asynccontextmanager
async def _scan(*args: str) -> AsyncIterator[_Scan]:
    process = await asyncio.create_subprocess_exec(
        sys.executable,
        "-m",
        "cobot_hmi.cli",
        "scan",
        *args,
        stdout=asyncio.subprocess.PIPE,
        stderr=asyncio.subprocess.PIPE,
    )
    scan = _Scan(process)
    try:
        yield scan
    finally:
        await scan.kill()


async def test_scan_reports_a_slow_target_once_and_keeps_o2t_hex(
    target: Target, robot_host: str, plc_host: str
) -> None:
    """``scan --o2t-hex`` at the robot's sizes against the slow emulator: the words once on
    stderr and in the summary; the emulator receives the given bytes in every O→T packet
    through the slow phase and after it."""
    given = encode_command(command_from_json({"controlbox_do": {"3": True}, "tool_do": [True] * 6}))
    target.faults.t2o_interval_factor = FACTOR
    slow_words = "the target grants 10 ms but sends every "
    async with _scan(
        robot_host, "--port", str(target.tcp_port), "--local-host", plc_host,
        "--o2t-hex", given.hex(), "--stats",
        "--multiplier", "7",  # RPI × 512: a loaded machine's stalls time nothing out
    ) as scan:  # fmt: skip
        await eventually(lambda: scan.said(slow_words))
        await eventually(lambda: any('"slow_target":"the target grants' in s for s in scan.out))
        seen = target.connections()[0].packets_in
        await eventually(lambda: any(c.packets_in >= seen + 200 for c in target.connections()))
        assert len(scan.said(slow_words)) == 1, scan.err
        target.faults.reset()
        await eventually(lambda: scan.said("the target keeps its 10 ms grant again"))
        last = target.connections()[0]
        assert await scan.interrupt() == 0, scan.err
    assert len(scan.said(slow_words)) == 1, scan.err
    assert len(scan.said("keeps its 10 ms grant again")) == 1, scan.err
    assert last.o2t_data_hex == given.hex() and last.o2t_data_changes == 0
    summary = json.loads(scan.out[-1])["summary"]
    assert summary["slow_target"] is None, "it keeps its grant at the end"
    assert summary["gaps"] == 0 and summary["late"] > 0

    target.faults.t2o_interval_factor = FACTOR
    async with _scan(
        robot_host, "--port", str(target.tcp_port), "--local-host", plc_host,
    ) as scan:  # fmt: skip
        await eventually(lambda: scan.said(slow_words))
        assert await scan.interrupt() == 0, scan.err
    summary = json.loads(scan.out[-1])["summary"]
    assert summary["slow_target"].startswith(slow_words), "still slow at the end"


# --------------------------------------------------------------------------- the service


async def test_service_reports_a_slow_robot_once_and_clears(
    robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    """The connection status (REST, validated by its model) says it in words while it lasts;
    the event log has one connection event for it and one when it clears."""
    faults = TargetFaults(t2o_interval_factor=FACTOR)
    async with emulator(robot_host, faults=faults) as target:
        settings = service_settings(robot_host, target.tcp_port, plc_host, tmp_path)
        async with running_service(settings) as hmi:
            robot = hmi.service.default_robot
            store = hmi.service.store
            slow_words = f"the robot grants {settings.cell.rpi_ms:g} ms but sends every "
            kept_words = f"the robot keeps its {settings.cell.rpi_ms:g} ms grant again"
            token = await hmi.login(VIEWER)

            async def connection() -> dict[str, object]:
                async with hmi.client(token) as client:
                    answer = await client.get(f"/api/v1/robots/{robot.name}/status")
                assert answer.status_code == 200, answer.text
                status = models.RobotStatus.model_validate(answer.json())
                return status.connection.model_dump()

            async def reasons() -> list[str]:
                await store.flush_events()
                page = await store.events_page("connection", 100, 0, robot=robot.name)
                return [str(item.get("reason")) for item in reversed(page.items)]

            await _until(connection, lambda c: c["slow_target"] is not None)
            status = await connection()
            assert str(status["slow_target"]).startswith(slow_words)
            assert status["state"] == "connected" and status["gaps"] == 0
            # More windows of the slow robot: still one event.
            frames = (await robot.link.stats()).frames
            await _until(robot.link.stats, lambda s: s.frames >= frames + SLOW_FRAMES)
            assert [r for r in await reasons() if r.startswith(slow_words)] == [
                (await connection())["slow_target"]
            ]

            faults.reset()
            await _until(connection, lambda c: c["slow_target"] is None)
            frames = (await robot.link.stats()).frames
            await _until(robot.link.stats, lambda s: s.frames >= frames + KEPT_FRAMES)
            seen = await reasons()
            assert len([r for r in seen if r.startswith(slow_words)]) == 1, seen
            assert seen.count(kept_words) == 1, seen
            assert seen.index(kept_words) > seen.index(
                next(r for r in seen if r.startswith(slow_words))
            )
            assert robot.link.state is ConnectionState.CONNECTED
            assert robot.connection.losses == 0


async def _until(
    read: Callable[[], Awaitable[_T]], check: Callable[[_T], bool], timeout_s: float = DEADLINE_S
) -> _T:
    """Read until ``check`` holds (a generous functional deadline, not a timing figure)."""
    loop = asyncio.get_running_loop()
    end = loop.time() + timeout_s
    while not check(value := await read()):
        assert loop.time() < end, f"condition not reached in time: {value!r}"
        await asyncio.sleep(0.05)
    return value
