"""The health engine (issue 40) fed the emulated arm's program faster than real time, in
process: friction, heat and cycle-time detection, no false watch over 2,000 healthy cycles with
a cold start, the life law against a hand computation, the state document round trip, and the
accelerated arm against ``SimulatedRobot``'s own frames."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from cobot_hmi.arms import M1013_ARM
from cobot_hmi.cli.health_verb import HealthSimulation
from cobot_hmi.emulator.robot import RobotSettings, SimulatedRobot
from cobot_hmi.emulator.robot.accelerated import AcceleratedArm
from cobot_hmi.emulator.robot.wear import JointWear, Wear
from cobot_hmi.health import FrameBlock, HealthEngine
from cobot_hmi.health.life import LIFE_EXPONENT
from cobot_hmi.stored_format import FormatVersionError


def _report(sim: HealthSimulation) -> Any:
    return sim.engine.report()


def _verdicts(sim: HealthSimulation) -> list[str]:
    return [str(joint["verdict"]) for joint in _report(sim)["joints"]]


def _baselined(cold_start: bool = False) -> HealthSimulation:
    sim = HealthSimulation(cold_start=cold_start)
    sim.engine.begin_baseline("commissioning", "test", sim.now_s, cycles=50)
    sim.run(50)
    assert sim.engine.baseline is not None
    return sim


def _first_flagged(sim: HealthSimulation, joint: int, level: str, cycles: int) -> int | None:
    for cycle in range(1, cycles + 1):
        sim.run(1)
        verdicts = _verdicts(sim)
        others = [v for j, v in enumerate(verdicts, 1) if j != joint]
        assert others == ["ok"] * 5, f"cycle {cycle}: another joint flagged: {verdicts}"
        if verdicts[joint - 1] == level:
            return cycle
    return None


@pytest.mark.parametrize(
    ("joint", "percent", "level"), [(3, 10, "watch"), (3, 25, "act"), (2, 10, "watch")]
)
def test_friction_on_one_joint_is_flagged_on_that_joint_within_50_cycles(
    joint: int, percent: float, level: str
) -> None:
    sim = _baselined()
    sim.add_wear(joint, JointWear(friction_percent=percent))
    found = _first_flagged(sim, joint, level, 50)
    assert found is not None, _report(sim)["joints"]
    sim.run(50 - found)
    figures = _report(sim)["joints"][joint - 1]
    assert figures["verdict"] == level
    assert figures["friction_percent"] == pytest.approx(percent, abs=2.5)
    assert f"J{joint}: friction" in figures["reason"]
    assert "above its baseline of" in figures["reason"]


def test_no_false_watch_over_2000_healthy_cycles_with_a_cold_start() -> None:
    sim = _baselined()
    flagged: list[tuple[int, list[str]]] = []
    for block in range(40):
        if block == 20:
            sim.cool_down()  # a night: the next cycles start cold, the gears' friction high
        sim.run(50)
        report = _report(sim)
        verdicts = [str(j["verdict"]) for j in report["joints"]]
        if verdicts != ["ok"] * 6 or report["cycle_time"]["verdict"] != "ok":
            flagged.append((block, verdicts))
    assert sim.engine.cycles == 2050
    assert not flagged


def test_a_hot_motor_is_found_within_50_cycles() -> None:
    sim = _baselined()
    sim.add_wear(2, JointWear(hot_c=8.0))
    found = _first_flagged(sim, 2, "watch", 50)
    assert found is not None
    figures = _report(sim)["joints"][1]
    assert "hotter than its current explains" in figures["reason"]


def test_a_cycle_time_change_of_5_percent_is_found_within_50_cycles() -> None:
    sim = _baselined()
    before = sim.arm.duration_s
    sim.set_speed_fraction(0.4 * 0.9)
    assert sim.arm.duration_s / before - 1.0 == pytest.approx(0.05, abs=0.015)
    drift: Any = None
    for _ in range(50):
        sim.run(1)
        drift = _report(sim)["cycle_time"]
        if drift["drift_detected"]:
            break
    else:
        pytest.fail(f"no drift found within 50 cycles: {drift}")
    assert "longer than its baseline" in drift["reason"]


def test_life_used_matches_the_law_by_hand() -> None:
    engine = HealthEngine(M1013_ARM)
    step_s, seconds = 0.01, 3600.0
    n = int(seconds / step_s)
    t = np.arange(n, dtype=np.float64) * step_s
    velocity = np.tile([60.0, -30.0, 90.0, 0.0, 120.0, 45.0], (n, 1))
    torque = np.tile([100.0, 250.0, -60.0, 10.0, 5.0, 20.0], (n, 1))
    zeros = np.zeros((n, 6))
    for part in np.array_split(np.arange(n), 36):
        engine.observe(
            FrameBlock(
                t[part],
                zeros[part],
                velocity[part],
                torque[part],
                zeros[part],
                zeros[part],
                zeros[part] + 30.0,
                np.full(part.size, 14),
                np.ones(part.size, dtype=bool),
            )
        )
    report: Any = engine.report()
    for j, rating in enumerate(M1013_ARM.ratings):
        hours = (seconds - step_s) / 3600.0
        by_hand = (
            (abs(velocity[0, j]) / rating.rated_speed_deg_s)
            * (abs(torque[0, j]) / rating.rated_torque_nm) ** (10 / 3)
            * hours
        )
        used = report["joints"][j]["life_used_percent"]
        assert used == pytest.approx(100.0 * by_hand / rating.rated_life_h, rel=0.01, abs=1e-4)
    assert pytest.approx(10 / 3) == LIFE_EXPONENT
    assert report["joints"][1]["life_remaining_h"] > 0


def test_the_state_document_restores_the_same_figures() -> None:
    sim = _baselined()
    sim.add_wear(3, JointWear(friction_percent=25))
    sim.run(20)
    document = sim.engine.to_document()
    assert document["format_version"] == 1
    restored = HealthEngine.from_document(document)
    assert restored.report() == sim.engine.report()
    newer = dict(document, format_version=2)
    with pytest.raises(FormatVersionError, match="robot health state version 2"):
        HealthEngine.from_document(newer)


def test_the_accelerated_arm_gives_simulated_robot_frames() -> None:
    settings = RobotSettings(current_noise_a=0.0, external_torque_noise_nm=0.0)
    arm = AcceleratedArm(settings)
    robot = SimulatedRobot(settings, start_s=0.0)
    wear = Wear(6)
    robot.wear.set(2, JointWear(friction_percent=40.0, coulomb_nm=1.0), 0.0)
    wear.set(2, JointWear(friction_percent=40.0, coulomb_nm=1.0), 0.0)
    # The recorded cycle is the robot's second: step the robot to the same instants.
    start = arm.recorded_start_s
    frames = arm.cycle(start, np.full(6, 25.0), wear, np.random.default_rng(1))
    for k in range(round(start * 100)):  # stepped as the recording was, at 100 Hz
        robot.produce_frame(k / 100)
    produced = [robot.produce_frame(float(t)) for t in frames.time_s]
    torque = np.array([f.joint_torque for f in produced])
    assert np.allclose(torque[:, :2], frames.torque_nm[:, :2], atol=1e-6)
    # J3's friction from the cold gear differs only by the temperature the cycle starts at.
    assert np.allclose(torque[:, 2], frames.torque_nm[:, 2], atol=0.05)
    assert not math.isclose(float(np.abs(frames.torque_nm[:, 2] - arm.torque[:, 2]).max()), 0.0)
