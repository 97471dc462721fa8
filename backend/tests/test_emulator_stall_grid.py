"""The target's T→O schedule after a stalled loop (a loaded host): the packets missed are skipped,
never sent in a burst, and the frames after it are still those of instants on the connection's
RPI grid, as a controller producing on its own clock sends them. They were not: the first packet
after the stall was computed for the late wake-up's instant, and every later one a whole RPI from
it, so the robot's instants moved off the grid by the stall's odd part, while the health engine
takes the spacing of samples as whole frame periods (end-to-end scenario 44 under CPU load).

Every frame fresh (``kinematic_refresh_ms`` 0, as scenario 44 runs the emulator): the target
reads the robot for each packet, at the instant the packet is due; the robot records those."""

from __future__ import annotations

import asyncio
import itertools
import time
from collections.abc import Sequence

from cobot_hmi.emulator.robot import RobotSettings, SimulatedRobot
from cobot_hmi.emulator.target import Target
from cobot_hmi.emulator.target_settings import TargetSettings
from cobot_hmi.generated.frames import Frame
from cobot_hmi.scanner.originator import Originator, OriginatorSettings
from emulator_harness import DEADLINE_S, FAST_TIMINGS
from waiting import eventually

RPI_S = 0.01
STALL_S = 0.047
"""Longer than two RPIs (the target then resynchronises), not a whole number of them."""
ON_GRID_S = 0.0005
"""The epoch instants are the loop's due times plus the two clocks' offset, read at each wake-up:
a few µs apart; a late wake-up's own instant is off by up to half an RPI."""


class RecordingRobot(SimulatedRobot):
    """The simulated robot, noting the instant of every frame the target asks it for."""

    def __init__(self, settings: RobotSettings) -> None:
        super().__init__(settings)
        self.instants_s: list[float] = []

    def produce_frame(self, now_s: float) -> Frame:
        self.instants_s.append(now_s)
        return super().produce_frame(now_s)


def _off_grid_s(instants_s: Sequence[float]) -> list[float]:
    """How far each instant is from the grid of the first one's RPIs."""
    first = instants_s[0]
    return [abs((t - first) / RPI_S - round((t - first) / RPI_S)) * RPI_S for t in instants_s]


def _stall() -> None:
    """Keep the loop busy (a host that gives it no CPU), the target's wake-ups waiting."""
    end = time.monotonic() + STALL_S
    while time.monotonic() < end:
        pass


async def test_after_a_stalled_loop_the_frames_stay_on_the_rpi_grid(
    robot_host: str, plc_host: str
) -> None:
    robot = RecordingRobot(RobotSettings(timings=FAST_TIMINGS, kinematic_refresh_ms=0.0))
    target = Target(TargetSettings(host=robot_host, tcp_port=0), robot)
    await target.start()
    originator = Originator(
        OriginatorSettings(
            robot_host=robot_host,
            tcp_port=target.tcp_port,
            local_host=plc_host,
            rpi_us=round(RPI_S * 1e6),
            timeout_multiplier=4,
        )
    )
    try:
        await originator.start()
        assert await originator.wait_connected(DEADLINE_S)
        await eventually(lambda: len(robot.instants_s) > 20)
        robot.instants_s.clear()
        await eventually(lambda: len(robot.instants_s) > 5)
        before = len(robot.instants_s)
        asyncio.get_running_loop().call_soon(_stall)
        await eventually(lambda: len(robot.instants_s) > before + 20)
        instants = list(robot.instants_s)
    finally:
        await originator.stop()
        await target.stop()
    steps = [round((b - a) / RPI_S) for a, b in itertools.pairwise(instants)]
    assert max(steps) >= 3, f"no stall seen: {steps}"  # the packets of the stall were skipped
    assert min(steps) >= 1  # never two frames of one instant: no burst
    worst_s = max(_off_grid_s(instants))
    assert worst_s < ON_GRID_S, f"a frame {worst_s * 1e3:.1f} ms off the RPI grid after the stall"
