"""The health engine (issue 40) fed the emulated arm's program faster than real time, in
process: friction, heat and cycle-time detection, no false watch over 2,000 healthy cycles with
a cold start, the life law against a hand computation, the state document round trip, and the
accelerated arm against ``SimulatedRobot``'s own frames.

The warm arm and its learned baseline are simulated once for the module (``_warm``,
``_commissioned``) and each test runs on its own copy: a copy is exactly the run it replaces
(the same frames, noise and figures after it), without its 150 cycles."""

from __future__ import annotations

import copy
import json
import math
import re
from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from cobot_hmi.arms import M1013_ARM
from cobot_hmi.cli.health_verb import HealthSimulation
from cobot_hmi.codec import decode_frame, encode_frame
from cobot_hmi.emulator.robot import RobotSettings, SimulatedRobot
from cobot_hmi.emulator.robot.accelerated import AcceleratedArm
from cobot_hmi.emulator.robot.wear import JointWear, Wear
from cobot_hmi.generated.frames import Frame
from cobot_hmi.health import FrameBlock, HealthEngine, HealthSettings
from cobot_hmi.health.life import LIFE_EXPONENT
from cobot_hmi.health.report import LIFE_DATE_HORIZON_H, life_end_date
from cobot_hmi.stored_format import FormatVersionError


def _report(sim: HealthSimulation) -> Any:
    return sim.engine.report()


def _verdicts(sim: HealthSimulation) -> list[str]:
    return [str(joint["verdict"]) for joint in _report(sim)["joints"]]


@pytest.fixture(scope="module")
def _warm() -> HealthSimulation:
    """The arm after its 100 warm-up cycles, no baseline yet (copied, never run itself)."""
    return HealthSimulation()


@pytest.fixture(scope="module")
def _commissioned(_warm: HealthSimulation) -> HealthSimulation:
    """The warm arm with a baseline learned from its next 50 cycles (copied, never run)."""
    sim = copy.deepcopy(_warm)
    sim.engine.begin_baseline("commissioning", "test", sim.now_s, cycles=50)
    sim.run(50)
    assert sim.engine.baseline is not None
    return sim


@pytest.fixture
def sim(_commissioned: HealthSimulation) -> HealthSimulation:
    """A baselined arm of the test's own (``HealthSimulation()``, 50 cycles of baseline)."""
    return copy.deepcopy(_commissioned)


@pytest.fixture
def warm(_warm: HealthSimulation) -> HealthSimulation:
    """A warm arm of the test's own, no baseline (``HealthSimulation()``)."""
    return copy.deepcopy(_warm)


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
    joint: int, percent: float, level: str, sim: HealthSimulation
) -> None:
    sim.add_wear(joint, JointWear(friction_percent=percent))
    found = _first_flagged(sim, joint, level, 50)
    assert found is not None, _report(sim)["joints"]
    sim.run(50 - found)
    figures = _report(sim)["joints"][joint - 1]
    assert figures["verdict"] == level
    assert figures["friction_percent"] == pytest.approx(percent, abs=2.5)
    assert f"J{joint}: friction" in figures["reason"]
    assert "above its baseline of" in figures["reason"]


def test_no_false_watch_over_2000_healthy_cycles_with_a_cold_start(sim: HealthSimulation) -> None:
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


def test_a_hot_motor_is_found_within_50_cycles(sim: HealthSimulation) -> None:
    sim.add_wear(2, JointWear(hot_c=8.0))
    found = _first_flagged(sim, 2, "watch", 50)
    assert found is not None
    figures = _report(sim)["joints"][1]
    assert "hotter than its current explains" in figures["reason"]


def test_a_cycle_time_change_of_5_percent_is_found_within_50_cycles(sim: HealthSimulation) -> None:
    before = sim.arm.duration_s
    sim.set_speed_fraction(0.355)  # from 0.4: the program's moves slower, the dwells the same
    assert sim.arm.duration_s / before - 1.0 == pytest.approx(0.05, abs=0.002)
    drift: Any = None
    for _ in range(50):
        sim.run(1)
        drift = _report(sim)["cycle_time"]
        if drift["drift_detected"]:
            break
    else:
        pytest.fail(f"no drift found within 50 cycles: {drift}")
    assert "5.0 % longer than its baseline" in drift["reason"]
    assert drift["drift_detected"] is True


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
    # J2 works hard: a date; J5 hardly loaded: millennia of hours, no date; J4 still: neither.
    j2, j4, j5 = (report["joints"][j] for j in (1, 3, 4))
    assert re.fullmatch(r"\d{4}-\d{2}-\d{2}", j2["life_end_date"])
    assert j5["life_remaining_h"] > LIFE_DATE_HORIZON_H and j5["life_end_date"] is None
    assert (j4["life_remaining_h"], j4["life_end_date"]) == (None, None)


def test_the_life_end_date_stops_at_a_hundred_years() -> None:
    now_s = 1_796_601_600.0  # 2026-12-07 00:00 UTC
    assert life_end_date(now_s, 48.0) == "2026-12-09"
    assert life_end_date(now_s, 0.0) == "2026-12-07"
    assert life_end_date(now_s, -5.0) == "2026-12-07"  # rated life already reached: today
    assert life_end_date(now_s, LIFE_DATE_HORIZON_H) is not None
    for beyond in (LIFE_DATE_HORIZON_H + 1.0, 1e12, math.inf, math.nan, None):
        assert life_end_date(now_s, beyond) is None


def test_the_state_document_restores_the_same_figures(sim: HealthSimulation) -> None:
    sim.add_wear(3, JointWear(friction_percent=25))
    sim.run(20)
    document = sim.engine.to_document()
    assert document["format_version"] == 1
    restored = HealthEngine.from_document(document)
    assert restored.report() == sim.engine.report()
    json.dumps(document, allow_nan=False)  # strict JSON: a file or a database row takes it
    json.dumps(sim.engine.report(), allow_nan=False)  # plain Python values, no numpy scalars
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


def _cycle_frames(sim: HealthSimulation) -> FrameBlock:
    frames = sim.arm.cycle(sim.now_s, sim.temperatures, sim.wear, sim.rng)
    return FrameBlock(*frames)


def _feed(sim: HealthSimulation, block: FrameBlock) -> None:
    sim.engine.observe(block)
    sim.engine.end_cycle(sim.now_s, sim.now_s + sim.arm.duration_s)
    sim.now_s += sim.arm.duration_s


def test_a_knock_is_counted_with_where_it_happened_and_the_joint_watched(
    sim: HealthSimulation,
) -> None:
    block = _cycle_frames(sim)
    external = block.external_torque_nm.copy()
    external[300:305, 1] += 80.0  # J2 hits something: 80 N·m over its 44 N·m threshold
    state = block.robot_state.copy()
    state[305:] = 3  # the controller's protective stop (INTERRUPTED)
    _feed(sim, replace(block, external_torque_nm=external, robot_state=state))
    report = _report(sim)
    assert report["knocks"]["collisions"] == [0, 1, 0, 0, 0, 0]
    assert report["knocks"]["protective_stop"] == 1
    event = report["knocks"]["events"][0]
    assert event["kind"] == "collision"
    assert event["joint"] == 2
    assert event["joint_position_deg"] == pytest.approx(list(block.position_deg[300]), abs=0.01)
    joint = report["joints"][1]
    assert joint["verdict"] == "watch"
    assert "1 external-torque peak(s) over 44 N·m this shift" in joint["reason"]


def test_rebaselining_keeps_the_old_baseline_and_the_trend_spans_it(sim: HealthSimulation) -> None:
    sim.add_wear(3, JointWear(friction_percent=12))
    sim.run(50)
    assert _verdicts(sim)[2] == "watch"
    sim.engine.begin_baseline("reducer J3 changed", "maintenance", sim.now_s, cycles=30)
    sim.run(30)
    report = _report(sim)
    assert [b["reason"] for b in report["baselines"]] == ["commissioning", "reducer J3 changed"]
    assert report["baseline"]["id"] == 2
    j3 = report["joints"][2]
    assert j3["verdict"] == "ok"
    assert abs(j3["friction_percent"]) < 2.0
    assert j3["friction_percent_since_first_baseline"] == pytest.approx(12.0, abs=2.5)


def test_a_ramp_of_wear_reads_as_friction_rising_a_week(sim: HealthSimulation) -> None:
    sim.wear.set_time_factor(168.0, sim.now_s)  # a week of wear in each hour of frames
    sim.add_wear(3, JointWear(friction_percent=20, ramp_s=7 * 86_400.0))
    sim.run(600)  # 80 minutes of frames
    j3 = _report(sim)["joints"][2]
    assert j3["verdict"] in ("watch", "act")
    # +20 % a week of wear, 168 weeks of wear a week of frames.
    assert j3["friction_percent_per_week"] == pytest.approx(20.0 * 168.0, rel=0.2)
    assert "rising" in j3["reason"]


def test_bad_frames_are_dropped_and_counted_and_bad_shapes_refused(sim: HealthSimulation) -> None:
    block = _cycle_frames(sim)
    torque = block.torque_nm.copy()
    torque[10, 2] = math.nan
    times = block.time_s.copy()
    times[20] = times[5]  # out of order
    _feed(sim, replace(block, torque_nm=torque, time_s=times))
    assert sim.engine.dropped_frames == 2
    assert _report(sim)["dropped_frames"] == 2
    with pytest.raises(ValueError, match="torque_nm: expected shape"):
        sim.engine.observe(replace(block, torque_nm=block.torque_nm[:, :5]))
    with pytest.raises(ValueError, match="a cycle must end after it starts"):
        sim.engine.end_cycle(sim.now_s, sim.now_s - 1.0)
    sim.run(5)
    assert _verdicts(sim) == ["ok"] * 6


def test_the_engine_fed_as_the_service_will_feed_it_finds_worn_j3() -> None:
    """SimulatedRobot's own frames (stepped at 100 Hz without sockets, monitoring values
    refreshed every 100 ms as the real controller's), a second at a time, cut into cycles at
    the rising edges of the program's cycle marker register, as the service's cycle meter
    does with the trigger ``bit_output_registers.63:rising``."""
    settings = RobotSettings(
        cycle_marker_register=63,
        kinematic_refresh_ms=100.0,
        thermal_time_constant_s=5.0,  # the motors settle in seconds: no long warm-up to step
    )
    robot = SimulatedRobot(settings, start_s=0.0)
    engine = HealthEngine(M1013_ARM, HealthSettings(thermal_time_constant_s=5.0))
    times: list[float] = []
    frames: list[Frame] = []

    def flush() -> None:
        if frames:
            engine.observe(FrameBlock.from_frames(times, frames))
            times.clear()
            frames.clear()

    step = 0
    marker = True  # no edge at the first frame: a cycle starts at the first rising edge
    started: float | None = None
    for cycles, before in ((4, None), (50, "baseline"), (25, "wear")):
        if before == "baseline":
            engine.begin_baseline("commissioning", "test", step / 100, cycles=50)
        elif before == "wear":
            robot.wear.set(2, JointWear(friction_percent=25.0), step / 100)
        done = 0
        while done < cycles:
            now_s = step / 100
            frame = robot.produce_frame(now_s)
            times.append(now_s)
            frames.append(frame)
            rising = frame.bit_output_registers[63] and not marker
            marker = frame.bit_output_registers[63]
            if rising:
                flush()  # the frames up to the cycle's end first
                if started is not None:
                    engine.end_cycle(started, now_s)
                    done += 1
                started = now_s
            elif len(frames) >= 100:
                flush()
            step += 1
    report: Any = engine.report()
    assert [j["verdict"] for j in report["joints"]] in (
        ["ok", "ok", "watch", "ok", "ok", "ok"],
        ["ok", "ok", "act", "ok", "ok", "ok"],
    ), [j["reason"] for j in report["joints"]]
    # At the controller's 100 ms refresh this program gives a rough reference for J3's healthy
    # friction (docs/health.md, "Friction"): the wear is found, its size only roughly.
    assert report["joints"][2]["friction_percent"] > 10.0


def test_a_baseline_over_a_period_and_one_without_a_reason_refused(warm: HealthSimulation) -> None:
    sim = warm
    with pytest.raises(ValueError, match="a baseline needs a reason"):
        sim.engine.begin_baseline("  ", "test", sim.now_s, cycles=10)
    period_s = 20 * sim.arm.duration_s + 1.0
    sim.engine.begin_baseline("new program", "test", sim.now_s, until_s=sim.now_s + period_s)
    sim.run(19)
    assert sim.engine.baseline is None
    assert _report(sim)["learning"]["cycles"] == 19
    sim.run(2)  # the period ends within the 21st cycle: learned at its end
    report = _report(sim)
    assert report["baseline"]["reason"] == "new program"
    assert report["baseline"]["cycles"] == 21
    assert report["baseline"]["arm"] == "M1013"
    assert report["baseline"]["layout_version"] == 1


def test_a_block_from_the_undecoded_payloads_is_the_block_from_the_decoded_frames() -> None:
    """``FrameBlock.from_payloads`` (the frame records' raw bytes, read with numpy) gives the
    very arrays ``from_frames`` gives of the decoded frames: the robot powering on (servo off,
    its states changing) and running its program, a collision's external torque."""
    robot = SimulatedRobot(RobotSettings(cycle_marker_register=63), start_s=0.0)
    times = [k / 100 for k in range(1500)]
    frames = [robot.produce_frame(t) for t in times]
    frames[700] = frames[700]._replace(joint_external_torque=(0.0, -91.5, 0.0, 0.0, 0.0, 0.0))
    payloads = [encode_frame(frame) for frame in frames]
    decoded = FrameBlock.from_frames(times, [decode_frame(p) for p in payloads])
    raw = FrameBlock.from_payloads(times, payloads)
    for name in FrameBlock.__slots__:
        ours, theirs = getattr(raw, name), getattr(decoded, name)
        assert ours.dtype == theirs.dtype, name
        assert np.array_equal(ours, theirs), name
    assert not raw.servo_on.all() and raw.servo_on.any()
    assert len(set(raw.robot_state.tolist())) > 1
    with pytest.raises(ValueError, match="T→O payloads of 284 bytes"):
        FrameBlock.from_payloads(times[:2], [payloads[0], payloads[1][:-1]])
