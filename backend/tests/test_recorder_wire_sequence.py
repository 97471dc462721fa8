"""The frame's own wire sequence number on its way to the recording (issue 14, "each row has the
receive time and the frame's sequence number"): the originator hands every frame to ``on_frame``
with the encapsulation sequence number its T→O packet carried (CIP Vol 2 §2-6, §3-4.2), with
the native and the pure-Python pump alike; the hub keeps it beside its own counter in the item
the recorder and the WebSocket stream get.

The wire numbers are checked against packets whose numbers this test chose: datagrams sent
from the target's own loopback address (the originator takes T→O by connection ID and source
address) with numbers far ahead of the live stream and across the 32-bit wrap, each carrying a
frame the live stream never does, so the test tells its own frames apart by their content.
"""

from __future__ import annotations

import itertools
import socket

import pytest

from cobot_hmi.codec import Frame, encode_frame, zero_frame
from cobot_hmi.emulator.target import Target
from cobot_hmi.enip import io
from cobot_hmi.layout import ROBOT_STATES
from cobot_hmi.scanner.originator import Originator, OriginatorSettings
from cobot_hmi.service.robots.frame_notifier import FrameNotifier
from frame_support import CollectedFrames
from waiting import eventually

pytestmark = pytest.mark.timeout(120)

DEADLINE_S = 20.0
EMERGENCY_STOP = next(s.value for s in ROBOT_STATES if s.name == "EMERGENCY_STOP")
JUMP: int = 0x7FFF_FFF0
"""Ahead of the last number by just under half the 32-bit range: newer (Vol 2 §3-4.2)."""


@pytest.mark.both_pumps
async def test_on_frame_carries_each_packets_wire_sequence_number(
    target: Target, robot_host: str, plc_host: str
) -> None:
    seen: list[tuple[Frame, int]] = []
    settings = OriginatorSettings(
        robot_host=robot_host,
        tcp_port=target.tcp_port,
        local_host=plc_host,
        rpi_us=10_000,
        timeout_multiplier=7,  # RPI × 512: the connection outlives the silence below
    )
    originator = Originator(
        settings, on_frame=lambda frame, _payload, _at, wire: seen.append((frame, wire))
    )
    await originator.start()
    try:
        assert await originator.wait_connected(DEADLINE_S)
        await eventually(lambda: len(seen) >= 50, DEADLINE_S)
        # The live stream: one number per packet, so consecutive frames step by one except
        # where the scanner counted packets it did not deliver.
        live = [wire for _, wire in seen]
        steps = [(b - a) & 0xFFFF_FFFF for a, b in itertools.pairwise(live)]
        assert all(step >= 1 for step in steps)
        stats = originator.stats()
        assert sum(step - 1 for step in steps) <= stats.gaps + stats.duplicates

        # The live stream falls silent, and what it sent has arrived, before ours go: the
        # second jump brings the numbers round the 32-bit circle close behind the live ones, so
        # a live packet arriving between ours would be newer than it and ours after it stale.
        target.faults.t2o_silent = True
        (connection,) = target._by_o2t.values()

        def drained() -> bool:
            (info,) = target.connections()
            return (
                not connection.t2o_streaming and originator.stats().packets_in >= info.packets_out
            )

        await eventually(drained, DEADLINE_S)
        link = originator._link  # the live connection's numbers, as a sniffer would see them
        assert link is not None and link.sequence.last_encap_seq is not None
        last_encap = link.sequence.last_encap_seq
        last_cip = link.sequence.last_cip_seq or 0
        chosen = [
            (last_encap + JUMP) & 0xFFFF_FFFF,
            (last_encap + 2 * JUMP) & 0xFFFF_FFFF,
            (last_encap + 2 * JUMP + 1) & 0xFFFF_FFFF,
            (last_encap + 2 * JUMP + 7) & 0xFFFF_FFFF,  # numbers the scanner never saw between
        ]
        numbers = [last_encap, *chosen]
        assert any(b < a for a, b in zip(numbers, chosen, strict=False)), "crosses 2³²"
        ours = [
            zero_frame()._replace(robot_state=EMERGENCY_STOP, joint_position=(float(n),) * 6)
            for n in range(len(chosen))
        ]
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender:
            sender.bind((robot_host, 0))  # the target's address, not its port: still its T→O
            for n, (wire, frame) in enumerate(zip(chosen, ours, strict=True)):
                packet = io.encode_io(
                    link.t2o_id, wire, (last_cip + 1 + n) & 0xFFFF, encode_frame(frame)
                )
                sender.sendto(packet, (plc_host, 2222))
        await eventually(
            lambda: sum(f.robot_state == EMERGENCY_STOP for f, _ in seen) >= 4, DEADLINE_S
        )
    finally:
        await originator.stop()
    delivered = [(frame, wire) for frame, wire in seen if frame.robot_state == EMERGENCY_STOP]
    assert [wire for _, wire in delivered] == chosen
    assert [frame.joint_position[0] for frame, _ in delivered] == [0.0, 1.0, 2.0, 3.0]


def test_every_consumer_gets_the_wire_number_beside_the_notifier_s_counter() -> None:
    """Every consumer of a robot's frames (the recorder, the stream, ``latest``) gets
    ``FrameRecord(seq, received_at_s, frame, t2o_sequence, raw)``; ``seq`` counts the frames
    published whatever the wire numbers do (a step there is a frame lost after the scanner)."""
    notifier = FrameNotifier("r")
    history = CollectedFrames(notifier, 10, name="history")
    wires = [0xFFFF_FFFE, 0xFFFF_FFFF, 0, 5]
    raw = encode_frame(zero_frame())
    for i, wire in enumerate(wires):
        notifier.publish(zero_frame(), raw, 1000.0 + i * 0.01, wire)
    records = history.take()
    assert [(r.seq, r.t2o_sequence) for r in records] == list(zip([1, 2, 3, 4], wires, strict=True))
    assert all(r.raw is raw for r in records)
    assert notifier.latest is not None and notifier.latest.t2o_sequence == 5
