"""The health engine's frames on the robot's own clock (``service.health.producer_clock``): a
frame's time is its T→O sequence number at the granted API from an anchor, not when it was
received. A loaded host receives late packets in bursts (one 10 ms spacing as 20-110 ms, the
next as ~0 ms), and the engine, which takes sample spacings as whole periods, read a +25 %
friction as -7.7 % (e2e 44). These feed ``ProducerClock`` blocks as ``RobotHealth`` does."""

from __future__ import annotations

import random

import numpy as np

from cobot_hmi.arms import M1013_ARM
from cobot_hmi.codec import Frame
from cobot_hmi.emulator.robot import RobotSettings, SimulatedRobot
from cobot_hmi.emulator.robot.wear import JointWear
from cobot_hmi.health import FrameBlock, HealthEngine
from cobot_hmi.service.health.monitor import ReceiveToProducer
from cobot_hmi.service.health.producer_clock import TAIL_S, ProducerClock

API_S = 0.01
BLOCK = 500
"""Frames a block: five seconds at 10 ms, the service's ``health_refresh_s``."""


def _bursty(count: int, seed: int, start_s: float = 1.7e9, stall_p: float = 0.03) -> np.ndarray:
    """Receive times of ``count`` packets produced every ``API_S``: now and then (``stall_p``
    of the packets) the producer stalls 20-110 ms and sends the packets due meanwhile at once
    when it wakes (each a few µs after the one before), as a loaded host's scan showed."""
    rng = random.Random(seed)
    received = []
    k = 0
    while k < count:
        due_s = start_s + k * API_S
        if rng.random() < stall_p:
            stall_s = rng.uniform(0.02, 0.11)
            late = int(stall_s / API_S) + 1
            for j in range(min(late, count - k)):
                received.append(due_s + stall_s + j * 1e-5)
            k += late
        else:
            received.append(due_s)
            k += 1
    times = np.array(received[:count])
    return np.maximum.accumulate(times)


def _feed(
    clock: ProducerClock, received_s: np.ndarray, sequences: np.ndarray | None, block: int = BLOCK
) -> np.ndarray:
    out = [
        clock.times(
            received_s[i : i + block],
            None if sequences is None else sequences[i : i + block],
            API_S,
        )
        for i in range(0, received_s.size, block)
    ]
    return np.concatenate(out)


def test_bursty_receive_times_give_exact_spacings() -> None:
    received = _bursty(6000, seed=1)
    assert np.sum(np.abs(np.diff(received) - API_S) > 1e-3) > 100  # the bursts are there
    clock = ProducerClock()
    producer = _feed(clock, received, np.arange(6000, dtype=np.int64) + 123)
    np.testing.assert_allclose(np.diff(producer), API_S, rtol=0, atol=1e-6)
    assert np.all(producer <= received + 1e-9)  # a packet arrives late, never early
    assert clock.runs == 1


def test_sequence_wraps_around_32_bits() -> None:
    received = _bursty(1000, seed=2)
    sequences = (np.arange(1000, dtype=np.int64) + 2**32 - 400) & 0xFFFF_FFFF
    clock = ProducerClock()
    producer = _feed(clock, received, sequences, block=300)
    np.testing.assert_allclose(np.diff(producer), API_S, rtol=0, atol=1e-6)
    assert clock.runs == 1


def test_reconnection_restarts_the_anchor() -> None:
    first = _bursty(700, seed=3)
    second = _bursty(700, seed=4, start_s=float(first[-1]) + 2.5)
    received = np.concatenate([first, second])
    # The new connection counts from 0 again: backwards, a new run.
    sequences = np.concatenate([np.arange(700) + 90_000, np.arange(700)]).astype(np.int64)
    clock = ProducerClock()
    producer = _feed(clock, received, sequences, block=400)
    assert clock.runs == 2
    np.testing.assert_allclose(np.diff(producer[:700]), API_S, rtol=0, atol=1e-6)
    np.testing.assert_allclose(np.diff(producer[700:]), API_S, rtol=0, atol=1e-6)
    assert producer[700] == second[0]  # anchored on the new run's on-time first frame
    # A new connection whose count runs far ahead (past what the gap's time allows): new run.
    clock = ProducerClock()
    ahead = np.concatenate([np.arange(700) + 5, np.arange(700) + 10_000_000]).astype(np.int64)
    producer = _feed(clock, received, ahead, block=400)
    assert clock.runs == 2
    assert abs(producer[700] - second[0]) < 1e-9


def test_unknown_sequences_fall_back_to_receive_times() -> None:
    received = _bursty(900, seed=5)
    clock = ProducerClock()
    assert np.array_equal(_feed(clock, received, None, block=300), received)
    assert np.array_equal(clock.times(received, np.full(900, -1, dtype=np.int64), API_S), received)
    assert np.array_equal(clock.times(received, np.arange(900, dtype=np.int64), None), received)
    # Sequences known again: a new anchor.
    later = received + 20.0
    producer = clock.times(later, np.arange(900, dtype=np.int64), API_S)
    np.testing.assert_allclose(np.diff(producer), API_S, rtol=0, atol=1e-6)
    assert clock.runs == 1


def test_a_slow_producer_clock_stays_near_the_receive_times() -> None:
    """A producer whose packets come every 10.002 ms (200 ppm slow) for an hour: the
    sequence's times at the API would fall behind by 0.72 s; each frame takes the lag of the
    frames after it, so they stay within a tail's drift of the receive times."""
    count = 360_000
    received = 1.7e9 + np.arange(count) * (API_S * 1.0002)
    clock = ProducerClock()
    producer = _feed(clock, received, np.arange(count, dtype=np.int64))
    lag = received - producer
    assert lag.min() >= -1e-6
    assert lag.max() <= TAIL_S * 0.0002 + 1e-6
    assert clock.runs == 1
    np.testing.assert_allclose(np.diff(producer), API_S * 1.0002, rtol=0, atol=1e-4)


def test_packets_skipped_without_counting_keep_their_spacing() -> None:
    """A producer that now and then skips 1-6 packets on its grid without counting them (the
    emulator after a stalled loop), its other packets received in bursts: each frame's time is
    its instant on the producer's grid (one anchor for the whole run), skips in a block's tail
    taken at the next block's start. (A frame late by more than a skip that follows it cannot
    be told from one on time after the skip: it takes the skip's lag. Here the frames before a
    skip are on time, as an emulator's are: its stall ends in the skip, not in a burst.)"""
    rng = random.Random(7)
    count, instants = 4000, []
    slot = 0
    for k in range(count):
        if k % BLOCK < BLOCK - 40 and rng.random() < 0.02:
            slot += rng.randint(1, 6)
        instants.append(slot)
        slot += 1
    due = 1.7e9 + np.array(instants) * API_S
    late = _bursty(count, seed=8) - (1.7e9 + np.arange(count) * API_S)
    for skip in np.flatnonzero(np.diff(instants) > 1):
        late[max(0, skip - 12) : skip + 1] = 0.0
    received = np.maximum.accumulate(due + late)
    assert np.sum(late > 1e-3) > 100  # the bursts are there
    assert np.any(np.diff(instants) > 1)
    clock = ProducerClock()
    producer = _feed(clock, received, np.arange(count, dtype=np.int64))
    np.testing.assert_allclose(producer - due, 0.0, rtol=0, atol=1e-6)
    assert clock.runs == 1


def test_cycle_boundaries_map_to_their_frames() -> None:
    received = _bursty(3000, seed=6)
    clock = ProducerClock()
    mapped = ReceiveToProducer()
    for i in range(0, 3000, BLOCK):
        part = received[i : i + BLOCK]
        mapped.add(part, clock.times(part, np.arange(i, i + part.size, dtype=np.int64), API_S))
    producer = 1.7e9 + np.arange(3000) * API_S
    for index in (1, 499, 500, 1234, 2999):
        assert abs(mapped.producer_s(float(received[index])) - producer[index]) < 1e-6


def _frictions(seed: int, stall_p: float, producer_clock: bool) -> list[float | None]:
    """Each joint's friction % of an emulated M1013 (every frame fresh, as in e2e 44) whose J3
    wears +25 % once a baseline of its first two whole cycles is learned, its frames received
    in bursts (``stall_p``) and fed in blocks of five seconds, the cycles cut at the receive
    times of the cycle marker's rising edges (the cycle meter's)."""
    marker_register, start_s, count = 63, 1000.0, 9000
    robot = SimulatedRobot(
        RobotSettings(
            cycle_marker_register=marker_register,
            kinematic_refresh_ms=0.0,
            temperature_rise_at_rated_current_c=0.0,
            seed=seed,
        ),
        start_s=0.0,
    )
    received = _bursty(count, seed, start_s=start_s, stall_p=stall_p)
    engine, clock, mapped = HealthEngine(M1013_ARM), ProducerClock(), ReceiveToProducer()
    marker, last_edge, worn = True, None, False
    cycles: list[tuple[float, float]] = []
    for i in range(0, count, BLOCK):
        part = received[i : i + BLOCK]
        frames: list[Frame] = []
        for k in range(i, i + part.size):
            if engine.baseline is not None and not worn:
                robot.wear.set(2, JointWear(friction_percent=25.0), start_s + k * API_S)
                worn = True
            frame = robot.produce_frame(start_s + k * API_S)
            frames.append(frame)
            level = frame.bit_output_registers[marker_register]
            if level and not marker:
                if last_edge is not None:
                    cycles.append((last_edge, float(received[k])))
                last_edge = float(received[k])
            marker = level
        sequences = np.arange(i, i + part.size, dtype=np.int64) if producer_clock else None
        times = clock.times(part, sequences, API_S)
        mapped.add(part, times)
        engine.observe(FrameBlock.from_frames(times.tolist(), frames))
        while cycles and cycles[0][1] <= part[-1]:
            start, end = cycles.pop(0)
            engine.end_cycle(mapped.producer_s(start), mapped.producer_s(end))
            if engine.learning is None and not engine.history:
                engine.begin_baseline("test", "test", end, cycles=2)
    assert worn
    return engine.friction_percent()


def test_bursty_frames_on_the_producer_clock_read_as_frames_on_time() -> None:
    """The figures of frames received in bursts, on the producer's clock, are those of the
    same frames received on time (on receive times, seed 1 with a stall every 10 packets read
    a healthy J2 at +7.8 % where on time it reads 0.0 %)."""
    for seed in (1, 3):
        on_time = _frictions(seed, 0.0, producer_clock=False)
        bursty = _frictions(seed, 0.1, producer_clock=True)
        assert on_time[2] is not None and on_time[2] > 10.0  # the wear is seen
        for joint, (expected, got) in enumerate(zip(on_time, bursty, strict=True)):
            if expected is None:
                continue
            assert got is not None and abs(got - expected) < 0.05, (seed, joint, on_time, bursty)
