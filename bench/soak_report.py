"""``bench/soak``'s end: what the service recorded and audited, against what the clients saw.

Frames: the recording of each robot (exported through the history API as Parquet: receive time,
the service's ``seq``, the wire's ``t2o_sequence`` and the sixteen ControlBox outputs) says what
the service took (``seq`` of its last frame), what it recorded (rows) and what it did not (steps
of ``seq``), and what the wire lost (steps of ``t2o_sequence`` between consecutive frames). Each
loss is put in one of three heaps by its time: the fault that explains it (a killed or lossy
robot's packets, frames not recorded while the disk was full, the stalled client's frames),
another fault's window, or outside every fault (the target: none).

Writes: every write the writer saw confirmed must be in the audit as confirmed (the same robot
and the same sixteen outputs) and in the recording (a frame of that robot between the request
and the answer showing those outputs).
"""

from __future__ import annotations

import io
from collections import Counter
from dataclasses import dataclass
from typing import Any

import httpx
import numpy as np
import numpy.typing as npt
import pyarrow as pa
import pyarrow.parquet as pq
from soak_clients import OUTPUTS, WIRE_RESTART_STEP, StreamClient, WriteRecord
from soak_faults import DISK, KILL, LOSS, LOSS_SETTLE_S, RECOVERY_S, STALL, FaultRecord

from cobot_hmi.history.schema import ELEMENTS

EXPECTED, OTHER, OUTSIDE = "the fault's own", "in another fault's window", "outside faults"
STARTUP = "while starting"
HEAPS = (EXPECTED, OTHER, OUTSIDE, STARTUP)
RECORDER_LAG_S = 2.0
"""A full disk can cost the frames of the batch being written when it filled (flushed every
1–1.5 s): the disk fault's window opens this much before the disk filled."""


@dataclass
class Recording:
    t: npt.NDArray[np.float64]
    seq: npt.NDArray[np.int64]
    wire: npt.NDArray[np.int64]
    """-1 where not kept"""
    outputs: npt.NDArray[np.int64]
    """The sixteen ControlBox outputs as one number, output i bit i."""


async def fetch_recording(
    http: httpx.AsyncClient, base_url: str, robot: str, since: float, until: float
) -> Recording:
    answer = await http.get(
        f"{base_url}/api/v1/robots/{robot}/export",
        params={
            "from": f"{since:.6f}",
            "to": f"{until:.6f}",
            "format": "parquet",
            "fields": "controlbox_do",
        },
        timeout=600,
    )
    answer.raise_for_status()
    table = pq.read_table(io.BytesIO(answer.content))
    t = table.column("time").cast(pa.int64()).to_numpy().astype(np.float64) / 1e6
    seq = table.column("seq").to_numpy().astype(np.int64)
    wire = table.column("t2o_sequence").cast(pa.int64()).fill_null(-1).to_numpy()
    outputs = np.zeros(len(t), dtype=np.int64)
    # An export names each element as the screen labels it (controlbox_do.DO1, history.schema).
    names = {e.name: e.export_name for e in ELEMENTS if e.field.name == "controlbox_do"}
    for i in range(OUTPUTS):
        column = table.column(names[f"controlbox_do.{i}"])
        bits = column.fill_null(False).to_numpy(zero_copy_only=False)
        outputs |= bits.astype(np.int64) << i
    return Recording(t, seq, wire.astype(np.int64), outputs)


def wire_steps(rec: Recording) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.int64]]:
    """Between each two consecutive frames: whether the service took both one after the other
    (its ``seq`` steps by one) with their wire numbers kept, and the wire number's step."""
    known = (np.diff(rec.seq) == 1) & (rec.wire[:-1] >= 0) & (rec.wire[1:] >= 0)
    return known, (rec.wire[1:] - rec.wire[:-1]) % (1 << 32)


def wire_gap_times(rec: Recording) -> npt.NDArray[np.float64]:
    """Receive times of the frames that followed lost packets (within one connection)."""
    known, steps = wire_steps(rec)
    times: npt.NDArray[np.float64] = rec.t[1:][known & (steps > 1) & (steps <= WIRE_RESTART_STEP)]
    return times


def first_after(rec: Recording, t: float) -> float | None:
    i = int(np.searchsorted(rec.t, t, side="right"))
    return float(rec.t[i]) if i < len(rec.t) else None


def settle(faults: list[FaultRecord], recordings: dict[str, Recording]) -> None:
    """Recoveries read from the recordings: a loss's (the last frame after a gap within
    ``RECOVERY_S`` of clearing it, or the first frame after it; a gap later than that, until
    ``LOSS_SETTLE_S``, is a loss that did not stop) and a full disk's (the first frame recorded
    again, on every robot: the recording's own clock, no polling's)."""
    for fault in faults:
        if fault.kind == LOSS:
            rec = recordings[fault.target]
            gaps = wire_gap_times(rec)
            tail = gaps[(gaps > fault.ended) & (gaps <= fault.ended + LOSS_SETTLE_S)]
            fault.pending = False
            if np.any(tail > fault.ended + RECOVERY_S):
                fault.notes.append("packets still lost after the loss was cleared")
            elif len(tail):
                fault.recovered = float(tail.max())
            else:
                fault.recovered = first_after(rec, fault.ended)
        elif fault.kind == DISK:
            fault.pending = False
            again = [first_after(rec, fault.ended) for rec in recordings.values()]
            if fault.recovered is not None and all(t is not None for t in again):
                fault.recovered = min(fault.recovered, max(t for t in again if t is not None))


class Heaps:
    """Frames lost, by heap: the fault's own, another fault's window, outside faults, or while
    starting (before ``started``: the service up, the clients connecting; not judged)."""

    def __init__(
        self, own: list[tuple[float, float]], every: list[tuple[float, float]], started: float
    ) -> None:
        self.own, self.every, self.started = own, every, started
        self.frames: Counter[str] = Counter()
        self.events: Counter[str] = Counter()
        self.outside_at: list[float] = []

    def add(self, t: float, frames: int, own: list[tuple[float, float]] | None = None) -> None:
        """A loss of ``frames`` at ``t``; ``own``: this loss's own fault windows, if not the
        heaps'."""
        if t < self.started:
            heap = STARTUP
        elif any(a <= t <= b for a, b in (self.own if own is None else own)):
            heap = EXPECTED
        elif any(a <= t <= b for a, b in self.every):
            heap = OTHER
        else:
            heap = OUTSIDE
            self.outside_at.append(t)
        self.frames[heap] += frames
        self.events[heap] += 1

    def text(self) -> str:
        return ", ".join(
            f"{self.frames[h]} {h} ({self.events[h]} gaps)"
            for h in HEAPS
            if h != STARTUP or self.frames[h]
        )


def every_window(faults: list[FaultRecord]) -> list[tuple[float, float]]:
    return [f.window(RECORDER_LAG_S, RECORDER_LAG_S) for f in faults]


def wire_windows(faults: list[FaultRecord], robot: str) -> list[tuple[float, float]]:
    return [f.window(0.1, 0.1) for f in faults if f.kind in (KILL, LOSS) and f.target == robot]


def disk_windows(faults: list[FaultRecord]) -> list[tuple[float, float]]:
    return [f.window(RECORDER_LAG_S, 1.0) for f in faults if f.kind == DISK]


def recording_losses(
    rec: Recording,
    faults: list[FaultRecord],
    robot: str,
    *,
    started: float,
    retention_deleted: bool,
) -> dict[str, Any]:
    """Frames the recorder did not keep and packets the wire lost, in heaps. Frames before the
    first one kept are a loss unless retention deleted segments (then they are its)."""
    every = every_window(faults)
    recorder = Heaps(disk_windows(faults), every, started)
    wire = Heaps(wire_windows(faults, robot), every, started)
    restarts = Heaps(wire_windows(faults, robot), every, started)
    before_first = int(rec.seq[0] - 1) if len(rec.seq) else 0
    if before_first and not retention_deleted:
        recorder.add(float(rec.t[0]), before_first)
    steps = np.diff(rec.seq)
    backwards = int(np.count_nonzero(steps < 1))
    for i in np.nonzero(steps > 1)[0]:
        recorder.add(float(rec.t[i + 1]), int(steps[i] - 1))
    known, step_of = wire_steps(rec)
    for i in np.nonzero(known & (step_of != 1))[0]:
        step = int(step_of[i])
        if step == 0 or step > WIRE_RESTART_STEP:
            restarts.add(float(rec.t[i + 1]), 1)
        else:
            wire.add(float(rec.t[i + 1]), step - 1)
    return {
        "recorder": recorder,
        "wire": wire,
        "restarts": restarts,
        "backwards": backwards,
        "deleted": before_first if retention_deleted else 0,
        "received": int(rec.seq[-1]) if len(rec.seq) else 0,
        "recorded": len(rec.seq),
    }


def client_losses(
    clients: dict[str, list[StreamClient]],
    faults: list[FaultRecord],
    stall_robot: str,
    started: float,
) -> Heaps:
    """Frames WebSocket clients missed (``seq`` steps), in heaps: the stalled client's during
    its stall are the fault's own."""
    every = every_window(faults)
    stalls = [f.window(0.0, 0.5) for f in faults if f.kind == STALL]
    heaps = Heaps([], every, started)
    for robot, group in clients.items():
        for client in group:
            own = stalls if (robot, client.index) == (stall_robot, 0) else []
            for t, frames in client.ws_losses:
                heaps.add(t, frames, own)
    return heaps


def audit_outputs(row: dict[str, Any]) -> int | None:
    """The sixteen outputs a write's audit row asked for, as one number (None: not all)."""
    requested = row.get("requested")
    if not isinstance(requested, dict):
        return None
    keys = [f"controlbox_do.{i}" for i in range(OUTPUTS)]
    if not all(k in requested for k in keys):
        return None
    return sum(1 << i for i, k in enumerate(keys) if requested[k])


def check_writes(
    writes: list[WriteRecord],
    audit: list[dict[str, Any]],
    recordings: dict[str, Recording],
    faults: list[FaultRecord],
) -> dict[str, Any]:
    confirmed = [w for w in writes if w.status == 200]
    rows = [r for r in audit if r.get("action") == "write"]
    audited: Counter[tuple[str, int | None]] = Counter(
        (r["robot"], audit_outputs(r)) for r in rows if r.get("outcome") == "confirmed"
    )
    told: Counter[tuple[str, int | None]] = Counter((w.robot, w.pattern) for w in confirmed)
    not_audited = [w for w in confirmed if audited[(w.robot, w.pattern)] == 0]
    disk = disk_windows(faults)
    not_recorded: list[WriteRecord] = []
    unrecordable = 0
    for w in confirmed:
        if _shown(recordings[w.robot], w, 0.01):
            continue
        if any(a <= w.done and w.sent <= b for a, b in disk):
            unrecordable += 1
        else:
            not_recorded.append(w)
    # A write that was not confirmed must not have reached the robot either, unless it timed
    # out (the robot may show it later): one that did, answered with an error, is a write
    # the writer was told failed although it took effect.
    applied_unconfirmed = [
        w for w in writes if w.status not in (200, 504) and _shown(recordings[w.robot], w, 2.0)
    ]
    return {
        "attempts": len(writes),
        "confirmed": len(confirmed),
        "by_status": Counter(w.status for w in writes),
        "reasons": Counter(w.reason for w in writes if w.status != 200),
        "audit_rows": len(rows),
        "audited_confirmed": sum(audited.values()),
        "audit_outcomes": Counter(str(r.get("outcome")) for r in rows),
        "not_audited": not_audited,
        "audited_not_told": (audited - told).total(),
        "not_recorded": not_recorded,
        "unrecordable": unrecordable,
        "applied_unconfirmed": applied_unconfirmed,
    }


def _shown(rec: Recording, write: WriteRecord, after_s: float) -> bool:
    """Whether a frame of the recording shows the write's outputs, from its request until
    ``after_s`` after its answer."""
    first, last = np.searchsorted(rec.t, [write.sent - 0.01, write.done + after_s])
    return bool(np.any(rec.outputs[first:last] == write.pattern))


def alarm_counts(history: list[dict[str, Any]]) -> dict[tuple[str, str], Counter[str]]:
    """Transitions per (robot, alarm key)."""
    out: dict[tuple[str, str], Counter[str]] = {}
    for row in history:
        out.setdefault((row["robot"], row["key"]), Counter())[row["transition"]] += 1
    return out


def stream_alarm_counts(monitors: dict[str, StreamClient]) -> Counter[tuple[str, str, str]]:
    """(robot, key, transition) of the ``alarm`` events the robots' monitors saw."""
    out: Counter[tuple[str, str, str]] = Counter()
    for robot, monitor in monitors.items():
        for event in monitor.events:
            if event["kind"] == "alarm":
                out[(robot, event["alarm"]["key"], event["transition"])] += 1
    return out


def verdict(ok: bool) -> str:
    return "PASS" if ok else "FAIL"
