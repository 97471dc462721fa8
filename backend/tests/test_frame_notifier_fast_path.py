"""FrameNotifier's per-frame path on the cyclic thread (no lock, the offers inline, one set of
urgent registrations): every frame reaches every consumer, in order, and the dropped counts are
those of each consumer's own bounded queue, as ``Registration.offer`` counts them."""

from __future__ import annotations

import asyncio
import gc
import threading
import weakref
from collections import deque
from collections.abc import Sequence

from cobot_hmi.codec import zero_frame
from cobot_hmi.service.robots.frame_notifier import FrameNotifier, FrameRecord, Runs
from waiting import WAIT_DEADLINE_S, eventually


class _Consumer:
    def __init__(self, name: str, runs: Runs, queue_frames: int) -> None:
        self.name, self.runs, self.queue_frames = name, runs, queue_frames
        self.seqs: list[int] = []

    def on_frames(self, robot: str, records: Sequence[FrameRecord]) -> None:
        self.seqs.extend(record.seq for record in records)


def test_each_queue_keeps_its_newest_frames_and_counts_the_rest_as_offer_does() -> None:
    notifier = FrameNotifier("r")
    sizes = (1, 3, 7, 50)
    consumers = [_Consumer(f"c{size}", Runs.THREAD, size) for size in sizes]
    registrations = [notifier.add(consumer) for consumer in consumers]
    references: list[deque[int]] = [deque(maxlen=size) for size in sizes]
    reference_dropped = [0] * len(sizes)
    frame = zero_frame()
    for i in range(1, 41):
        notifier.publish(frame, b"raw", 1000.0 + i, i + 100)
        for k, reference in enumerate(references):  # Registration.offer's rule, by hand
            if len(reference) == reference.maxlen:
                reference_dropped[k] += 1
            reference.append(i)
        if i % 13 == 0:
            for registration in registrations:
                registration.deliver()
            for k, consumer in enumerate(consumers):
                assert consumer.seqs[-len(references[k]) :] == list(references[k])
                references[k].clear()
    for registration in registrations:
        registration.deliver()
    assert [r.dropped for r in registrations] == reference_dropped
    for registration, consumer in zip(registrations, consumers, strict=True):
        assert registration.delivered + registration.dropped == 40
        assert consumer.seqs == sorted(set(consumer.seqs))
    record = notifier.latest
    assert record is not None and type(record) is FrameRecord
    assert record == (40, 1040.0, frame, 140, b"raw") and record.raw == b"raw"
    assert notifier.seq == 40


def test_a_consumer_thread_draining_while_the_cyclic_thread_publishes_misses_nothing() -> None:
    notifier = FrameNotifier("r")
    consumer = _Consumer("c", Runs.THREAD, 100_000)
    registration = notifier.add(consumer)
    frames = 20_000
    done = threading.Event()

    def produce() -> None:
        frame = zero_frame()
        for i in range(frames):
            notifier.publish(frame, b"", float(i), i)
        done.set()

    producer = threading.Thread(target=produce)
    producer.start()
    while not done.is_set():
        registration.deliver()
    producer.join()
    registration.deliver()
    assert consumer.seqs == list(range(1, frames + 1))
    assert (registration.delivered, registration.dropped) == (frames, 0)


async def test_an_urgent_consumer_is_woken_per_frame_until_it_is_no_longer_urgent() -> None:
    loop = asyncio.get_running_loop()
    notifier = FrameNotifier("r", frames_per_wake=1000)
    consumer = _Consumer("c", Runs.LOOP, 100)
    registration = notifier.add(consumer)
    notifier.bind_loop(loop)
    frame = zero_frame()
    notifier.publish(frame, b"", 1.0, 1)
    for _ in range(5):
        await asyncio.sleep(0)
    assert consumer.seqs == [], "not urgent: waits for its broadcast period"
    registration.urgent = True
    notifier.publish(frame, b"", 1.01, 2)
    await eventually(lambda: consumer.seqs == [1, 2], WAIT_DEADLINE_S)
    registration.urgent = False
    assert not registration.urgent
    notifier.publish(frame, b"", 1.02, 3)
    for _ in range(5):
        await asyncio.sleep(0)
    assert consumer.seqs == [1, 2]
    registration.urgent = True
    notifier.remove(registration)
    notifier.publish(frame, b"", 1.03, 4)
    for _ in range(5):
        await asyncio.sleep(0)
    assert consumer.seqs == [1, 2], "a removed registration is no longer served"
    assert notifier.registrations == ()


async def test_the_loops_wake_holds_its_notifiers_weakly_and_serves_each_once() -> None:
    loop = asyncio.get_running_loop()
    kept = FrameNotifier("kept", frames_per_wake=1)
    consumer = _Consumer("c", Runs.LOOP, 100)
    kept.add(consumer)
    kept.bind_loop(loop)
    kept.bind_loop(loop)  # bound again: still one turn per wake
    dropped = FrameNotifier("dropped", frames_per_wake=1)
    dropped.add(_Consumer("d", Runs.LOOP, 100))
    dropped.bind_loop(loop)
    gone = weakref.ref(dropped)
    del dropped
    gc.collect()
    assert gone() is None, "the wake does not keep a notifier alive"
    kept.publish(zero_frame(), b"", 1.0, 1)
    await eventually(lambda: consumer.seqs == [1], WAIT_DEADLINE_S)
    kept.publish(zero_frame(), b"", 1.01, 2)
    await eventually(lambda: consumer.seqs == [1, 2], WAIT_DEADLINE_S)
