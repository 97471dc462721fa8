"""T2OReceiver's per-frame counters with the settings and the granted API read once per
connection, not per frame: late frames judged at 1.5 RPI of the API granted (before and after
the reply), gaps, duplicates, stale packets, the interval window and the frames handed on."""

from __future__ import annotations

import asyncio

from cobot_hmi.codec import Frame, encode_frame, zero_frame
from cobot_hmi.enip import io
from cobot_hmi.scanner.connection.link import Link
from cobot_hmi.scanner.connection.originator_settings import OriginatorSettings
from cobot_hmi.scanner.connection.t2o_receive import T2OReceiver
from cobot_hmi.scanner.io_port import IoPort


async def test_counters_follow_the_granted_api() -> None:
    settings = OriginatorSettings("127.0.0.1", rpi_us=10_000)
    handed: list[tuple[int, int]] = []

    def on_frame(frame: Frame, _payload: bytes, _at: float, encap_seq: int) -> None:
        handed.append((frame.robot_state, encap_seq))

    receiver = T2OReceiver(settings, seed=lambda _frame: None, on_frame=on_frame)
    loop = asyncio.get_running_loop()
    link = Link(
        t2o_id=7,
        connection_serial=1,
        originator_serial=2,
        path=b"",
        target_host="127.0.0.1",
        o2t_api_us=10_000,
        t2o_api_us=10_000,
    )
    receiver.attach(
        link, IoPort("127.0.0.1", 0), lost=loop.create_future(), first_frame=loop.create_future()
    )
    payloads = [encode_frame(zero_frame()._replace(robot_state=n)) for n in range(4)]

    def packet(encap_seq: int, cip_seq: int, state: int, at_s: float) -> None:
        decoded = io.decode_io(io.encode_io(7, encap_seq, cip_seq, payloads[state]))
        receiver.t2o_packet(decoded, at_s)

    packet(1, 1, 1, 100.000)
    packet(2, 2, 2, 100.010)  # on time
    packet(3, 3, 1, 100.026)  # 16 ms: late at 10 ms (over 15)
    packet(4, 3, 1, 100.030)  # the same CIP count: a duplicate
    packet(3, 4, 2, 100.031)  # an older encapsulation number: stale
    assert (receiver.frames, receiver.late, receiver.duplicates, receiver.stale) == (3, 1, 1, 1)
    link.t2o_api_us = 20_000  # the reply grants T→O every 20 ms
    receiver.granted(20_000)
    packet(5, 4, 3, 100.052)  # 26 ms: on time at 20 ms (up to 30)
    packet(8, 7, 0, 100.090)  # 38 ms and two packets missed: late
    assert (receiver.frames, receiver.late, receiver.gaps) == (5, 2, 2)
    assert handed == [(1, 1), (2, 2), (1, 3), (3, 5), (0, 8)]
    figures = receiver.interval_figures()
    assert figures.count == 4 and figures.max_ms is not None
    assert abs(figures.max_ms - 38.0) < 1e-6
    assert receiver.packets_in == 6
