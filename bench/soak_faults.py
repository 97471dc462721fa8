"""``bench/soak``'s faults, one at a time, each with its end and its recovery measured.

Every fault notes when it began (``started``), when the thing it broke was whole again
(``ended``: the emulator accepts connections again, the loss is cleared, the broker accepts
connections, the client reads again, the filler file is gone) and when the service was whole
again (``recovered``): frames flowing from the restarted robot; no more lost packets; the edge
node connected with its births out; frames flowing to the client again; recording resumed.
All times are this machine's wall clock, the clock of the service's receive times.
"""

from __future__ import annotations

import asyncio
import errno
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import httpx
from service_bench_support import metrics, value_of
from soak_cell import READY_POLL_S, Cell
from soak_clients import BirthProbe, StreamClient, Writer

from cobot_hmi.service.recording.recorder import RETRY_S
from cobot_hmi.sparkplug.mqtt_client import RECONNECT_MAX_S, RECONNECT_MIN_S

RECOVERY_S = 2.0
"""The target: the service is whole again this long after the fault ended at the latest."""
RECOVERY_WAIT_S = 60.0
"""How long a fault waits for a recovery before it calls it missing."""
LOSS_SETTLE_S = 3.0
"""After clearing the loss: packets lost in the first ``RECOVERY_S`` are the fault's tail; one
lost after that (until this long after) is a loss that did not stop."""

KILL = "emulator kill -9"
LOSS = "T→O loss"
BROKER = "broker restart"
STALL = "client stops reading"
DISK = "state dir full"
KINDS = (KILL, LOSS, BROKER, STALL, DISK)
SHORT_NAMES = {"kill": KILL, "loss": LOSS, "broker": BROKER, "stall": STALL, "disk": DISK}
"""``--faults`` names."""


@dataclass
class FaultRecord:
    kind: str
    target: str
    started: float
    ended: float = 0.0
    recovered: float | None = None
    bound_s: float = RECOVERY_S
    notes: list[str] = field(default_factory=list)
    pending: bool = False
    """Its recovery is measured from the recording at the end."""

    @property
    def recovery_s(self) -> float | None:
        return None if self.recovered is None else max(0.0, self.recovered - self.ended)

    @property
    def passed(self) -> bool:
        recovery = self.recovery_s
        return recovery is not None and recovery <= self.bound_s

    def window(self, before_s: float = 0.0, after_s: float = 0.0) -> tuple[float, float]:
        """From its start to its recovery (or the longest wait, when there was none)."""
        end = self.recovered if self.recovered is not None else self.ended + RECOVERY_WAIT_S
        return self.started - before_s, max(end, self.ended) + after_s


@dataclass
class Soak:
    """What a fault may touch: the cell, the clients, the writer, an HTTP client."""

    cell: Cell
    clients: dict[str, list[StreamClient]]
    monitors: dict[str, StreamClient]
    writer: Writer
    http: httpx.AsyncClient
    loss_percent: float
    fault_s: float
    stall_robot: str
    faults: list[FaultRecord] = field(default_factory=list)

    async def scrape(self) -> dict[tuple[str, str], float]:
        answer = await self.http.get(self.cell.base_url + "/metrics")
        answer.raise_for_status()
        return metrics(answer.text)

    async def control(self, robot: str, path: str, body: dict[str, object]) -> None:
        """A request to a robot's control API, on a connection of its own (closed after, so
        the emulator's open file descriptors are its own when sampled)."""
        url = self.cell.robot(robot).control_url + path
        async with httpx.AsyncClient(timeout=10.0, trust_env=False) as client:
            (await client.post(url, json=body)).raise_for_status()


async def kill_emulator(soak: Soak, robot: str) -> FaultRecord:
    target = soak.cell.robot(robot)
    record = FaultRecord(KILL, robot, time.time())
    await asyncio.to_thread(soak.cell.kill_emulator, target)
    await asyncio.to_thread(soak.cell.start_emulator, target)
    record.ended = time.time()
    record.notes.append(f"emulator down {record.ended - record.started:.2f} s")
    record.recovered = await soak.monitors[robot].first_frame_after(record.ended, RECOVERY_WAIT_S)
    return record


async def lose_packets(soak: Soak, robot: str) -> FaultRecord:
    """Its recovery (when packets stopped going missing) comes from the recording at the end:
    the receive time of the last frame after a gap (soak_report.settle)."""
    gaps = "cobot_hmi_frame_gaps_total"
    before = value_of(await soak.scrape(), gaps, robot)
    record = FaultRecord(LOSS, robot, time.time(), pending=True)
    await soak.control(robot, "/faults", {"t2o_drop_percent": soak.loss_percent})
    await asyncio.sleep(soak.fault_s)
    await soak.control(robot, "/faults/clear", {})
    record.ended = time.time()
    await asyncio.sleep(LOSS_SETTLE_S)
    lost = value_of(await soak.scrape(), gaps, robot) - before
    record.notes.append(
        f"{soak.loss_percent:g} % for {soak.fault_s:g} s: {lost:.0f} packets lost (gap counter)"
    )
    return record


def _broker_bound_s(down_s: float) -> float:
    """paho's first reconnect attempt after an outage of ``down_s`` (its delay doubles from
    RECONNECT_MIN_S up to RECONNECT_MAX_S), from the broker's return, plus ``RECOVERY_S``."""
    attempt, delay = 0.0, float(RECONNECT_MIN_S)
    while attempt < down_s:
        attempt += delay
        delay = min(delay * 2, RECONNECT_MAX_S)
    return attempt - down_s + RECOVERY_S


async def restart_broker(soak: Soak) -> FaultRecord:
    broker = soak.cell.broker
    assert broker is not None
    before = await soak.scrape()
    reconnects = value_of(before, "cobot_hmi_sparkplug_reconnects_total")
    record = FaultRecord(BROKER, "mosquitto", time.time())
    await asyncio.to_thread(broker.stop)
    await asyncio.to_thread(broker.start, READY_POLL_S)
    record.ended = time.time()
    down_s = record.ended - record.started
    record.bound_s = _broker_bound_s(down_s)
    record.notes.append(f"broker down {down_s:.2f} s")
    probe = BirthProbe(broker.host, broker.port)
    await asyncio.to_thread(probe.start)
    try:
        # The probe's NBIRTH is exact; /metrics (born again after a reconnect) is the fallback
        # when the edge node got in first, an upper bound (a scrape takes its time).
        deadline = record.ended + RECOVERY_WAIT_S
        while time.time() < deadline and probe.born_at is None:
            now = await soak.scrape()
            if (
                value_of(now, "cobot_hmi_sparkplug_reconnects_total") > reconnects
                and value_of(now, "cobot_hmi_sparkplug_born") == 1
            ):
                record.recovered = time.time()
                break
            await asyncio.sleep(0.05)
        if probe.born_at is None and record.recovered is not None:
            await asyncio.sleep(0.5)  # its NBIRTH may still be on its way to the probe
        if probe.born_at is not None:
            record.recovered = probe.born_at
        else:
            record.notes.append("the edge node was born before the probe subscribed: polled")
    finally:
        await asyncio.to_thread(probe.stop)
    return record


async def stall_client(soak: Soak) -> FaultRecord:
    """A client stops reading; the service should cut it once its sends are stuck
    (``ws_stall_timeout_s``). When it reads again it first drains what its socket still holds,
    then finds the connection closed and opens a new one: the fault ends when that new
    connection begins (or, if it was never cut, when it reads again), and it has recovered
    when a frame the service received after it read again reaches it."""
    client = soak.clients[soak.stall_robot][0]
    metric = "cobot_hmi_ws_stalled_disconnects_total"
    stalled = value_of(await soak.scrape(), metric, soak.stall_robot)
    dropped = client.dropped_told
    record = FaultRecord(STALL, f"{soak.stall_robot} client {client.index}", time.time())
    client.pause()
    await asyncio.sleep(soak.fault_s)
    resumed = time.time()
    client.resume()
    flowing = await client.first_frame_after(resumed, RECOVERY_WAIT_S, arrival=True)
    reconnects = [t for t in client.connects if t >= resumed]
    record.ended = reconnects[-1] if reconnects and flowing is not None else resumed
    record.recovered = flowing
    cut = value_of(await soak.scrape(), metric, soak.stall_robot) - stalled
    record.notes.append(
        f"the service cut it {cut:g}×; it read again after {soak.fault_s:g} s and "
        + (
            f"reconnected {record.ended - resumed:.2f} s later"
            if reconnects
            else "was still connected"
        )
        + f"; 'dropped' notices for {client.dropped_told - dropped} frames"
    )
    return record


def _fill(path: Path) -> int:
    """Write zeros until the file system says it is full; the bytes written."""
    written = 0
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    try:
        for size in (1 << 20, 1 << 12, 1):
            chunk = bytes(size)
            while True:
                try:
                    written += os.write(fd, chunk)
                except OSError as error:
                    if error.errno != errno.ENOSPC:
                        raise
                    break
    finally:
        os.close(fd)
    return written


async def fill_state_dir(soak: Soak) -> FaultRecord:
    """Recovery: the recorder records again. Polled here (``cobot_hmi_history_recording`` back
    to 1, or the monitor's ``recording`` event, whichever says so first: an upper bound on a
    busy machine), then read from the recording at the end (its first frame after the space
    was freed, soak_report.settle)."""
    monitor = soak.monitors[soak.cell.robots[0].name]
    path = soak.cell.state / "soak-filler.bin"
    pauses = value_of(await soak.scrape(), "cobot_hmi_history_pauses_total")
    record = FaultRecord(DISK, "tmpfs", time.time(), pending=True)
    record.bound_s = RETRY_S + RECOVERY_S
    written = await asyncio.to_thread(_fill, path)
    await asyncio.sleep(soak.fault_s)
    paused = value_of(await soak.scrape(), "cobot_hmi_history_pauses_total") - pauses
    await asyncio.to_thread(path.unlink)
    record.ended = time.time()
    record.notes.append(
        f"filled with {written / 2**20:.0f} MiB for {soak.fault_s:g} s; recording paused "
        f"{paused:g}×"
    )
    deadline = record.ended + RECOVERY_WAIT_S
    while time.time() < deadline:
        if value_of(await soak.scrape(), "cobot_hmi_history_recording") == 1:
            record.recovered = time.time()
            break
        await asyncio.sleep(0.05)
    resumed = [
        e["time"]
        for e in monitor.events
        if e["kind"] == "recording" and e["state"] == "recording" and e["time"] >= record.ended
    ]
    if record.recovered is not None and resumed:
        record.recovered = min(record.recovered, resumed[0])
    return record


async def inject(soak: Soak, number: int, kinds: tuple[str, ...] = KINDS) -> FaultRecord:
    """Fault ``number`` (0, 1, …): the kinds in turn; the robot-side ones alternate robots."""
    kind = kinds[number % len(kinds)]
    names = [r.name for r in soak.cell.robots]
    cycle = number // len(kinds)
    if kind == KILL:
        return await kill_emulator(soak, names[cycle % len(names)])
    if kind == LOSS:
        return await lose_packets(soak, names[(cycle + 1) % len(names)])
    if kind == BROKER:
        return await restart_broker(soak)
    if kind == STALL:
        return await stall_client(soak)
    return await fill_state_dir(soak)
