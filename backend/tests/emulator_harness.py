"""The emulator as tests of issue 4 run it: the simulated robot behind the real EtherNet/IP target
on ``robot_host``, its control API on the same address (a free port), and our scanner (the
originator) on ``plc_host`` holding a class 1 connection, all in one asyncio loop.

Every state and fault is observed from the scanner's side: frames decoded from the T→O packets
the originator received, its counters and its connection states.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator, Callable
from dataclasses import dataclass, field

import httpx

from cobot_hmi.emulator.control_api import ControlApiServer, create_control_app
from cobot_hmi.emulator.robot import RobotSettings, SimulatedRobot, StateTimings
from cobot_hmi.emulator.target import Target
from cobot_hmi.emulator.target_settings import TargetSettings
from cobot_hmi.generated.frames import Frame
from cobot_hmi.layout import flag_fields
from cobot_hmi.scanner.originator import ConnectionState, Originator, OriginatorSettings
from conftest import free_tcp_port
from waiting import WAIT_DEADLINE_S

DEADLINE_S = WAIT_DEADLINE_S
"""A generous functional deadline, never a timing figure."""

FAST_TIMINGS = StateTimings(initializing_s=0.4, program_start_delay_s=0.4, safe_off_s=0.3)

Observation = tuple[int, tuple[bool, ...]]
"""A robot state and its five flags, as a frame carried them."""


def observe(frame: Frame) -> Observation:
    return frame.robot_state, tuple(getattr(frame, f.name) for f in flag_fields())


def flags(**set_flags: bool) -> tuple[bool, ...]:
    """The five flags in the table's order, those named set."""
    unknown = set(set_flags) - {f.name for f in flag_fields()}
    assert not unknown, unknown
    return tuple(set_flags.get(f.name, False) for f in flag_fields())


@dataclass
class Emulator:
    robot: SimulatedRobot
    target: Target
    api: httpx.AsyncClient
    plc_host: str
    originator: Originator | None = None
    observed: list[Observation] = field(default_factory=list)
    """Every change of (state, flags) the scanner received, in order."""
    connection_states: list[tuple[ConnectionState, str | None]] = field(default_factory=list)

    def _on_frame(self, frame: Frame, _payload: bytes, _at: float, _n: int) -> None:
        observation = observe(frame)
        if not self.observed or self.observed[-1] != observation:
            self.observed.append(observation)

    def _on_state(self, state: ConnectionState, reason: str | None) -> None:
        self.connection_states.append((state, reason))

    async def connect(self, **overrides: object) -> Originator:
        options: dict[str, object] = {
            "robot_host": self.target.settings.host,
            "tcp_port": self.target.tcp_port,
            "local_host": self.plc_host,
            "rpi_us": 10_000,
            "backoff_max_s": 0.5,
        }
        options.update(overrides)
        originator = Originator(
            OriginatorSettings(**options),  # type: ignore[arg-type]
            on_frame=self._on_frame,
            on_state=self._on_state,
        )
        self.originator = originator
        await originator.start()
        return originator

    @property
    def frame(self) -> Frame:
        assert self.originator is not None and self.originator.latest is not None
        return self.originator.latest[0]

    async def frame_where(
        self, check: Callable[[Frame], bool], timeout_s: float = DEADLINE_S
    ) -> Frame:
        """The first frame received from now on for which ``check`` holds."""
        assert self.originator is not None
        start = self.originator.frames
        end = asyncio.get_running_loop().time() + timeout_s
        while True:
            latest = self.originator.latest
            if self.originator.frames > start and latest is not None and check(latest[0]):
                return latest[0]
            assert asyncio.get_running_loop().time() < end, "no such frame in time"
            await asyncio.sleep(0.005)

    async def post(self, path: str, body: object = None, expect: int = 200) -> dict[str, object]:
        # The control API takes JSON only: an empty object when there are no fields.
        response = await self.api.post(path, json={} if body is None else body)
        assert response.status_code == expect, response.text
        data = response.json()
        assert isinstance(data, dict)
        return data


@contextlib.asynccontextmanager
async def running_emulator(
    robot_host: str, plc_host: str, settings: RobotSettings | None = None
) -> AsyncIterator[Emulator]:
    robot = SimulatedRobot(settings or RobotSettings(timings=FAST_TIMINGS))
    target = Target(TargetSettings(host=robot_host, tcp_port=0), robot)
    await target.start()
    control = ControlApiServer(
        create_control_app(robot, target), robot_host, free_tcp_port(robot_host)
    )
    emulator: Emulator | None = None
    try:
        await control.start()
        async with httpx.AsyncClient(base_url=f"http://{robot_host}:{control.port}") as api:
            emulator = Emulator(robot, target, api, plc_host)
            yield emulator
    finally:
        if emulator is not None and emulator.originator is not None:
            await emulator.originator.stop()
        await control.stop()
        await target.stop()
