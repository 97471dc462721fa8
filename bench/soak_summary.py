"""``bench/soak``'s figures: each minute's process figures, the targets, the end's printout.

Every check prints its figures with PASS or FAIL beside them (``Run.target``); soak_report.py
computes what they say of the recordings, the audit and the clients.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import time
from collections import Counter
from typing import Any

import httpx
from service_bench_support import value_of
from soak_cell import Cell, Sample, sample
from soak_clients import MqttWatcher
from soak_faults import Soak
from soak_report import (
    OUTSIDE,
    alarm_counts,
    check_writes,
    client_losses,
    recording_losses,
    stream_alarm_counts,
    verdict,
)

FLAT_SHARE = 0.05
JUDGED_FROM_MINUTE = 5
Samples = dict[int, dict[str, tuple[int, Sample]]]
"""minute → role → (pid, figures)"""


def clock(seconds: float) -> str:
    return f"{int(seconds // 60):02d}:{int(seconds % 60):02d}"


def load_average() -> str:
    return ", ".join(f"{x:.2f}" for x in os.getloadavg())


class Run:
    def __init__(self, args: argparse.Namespace, cell: Cell) -> None:
        self.args = args
        self.cell = cell
        self.started = time.time()
        self.samples: Samples = {}
        self.previous: dict[str, tuple[int, Sample]] = {}
        self.failures: list[str] = []

    def at(self, t: float) -> str:
        return clock(t - self.started)

    def sample_minute(self, minute: int) -> None:
        figures: dict[str, tuple[int, Sample]] = {}
        parts = []
        for role, pid in self.cell.processes().items():
            now = sample(pid)
            if now is None:
                continue
            figures[role] = (pid, now)
            cpu = ""
            before = self.previous.get(role)
            if before is not None and before[0] == pid:
                cpu = f", CPU {(now.cpu_s - before[1].cpu_s) / 60 * 100:.0f} %"
            parts.append(
                f"{role} {now.rss_bytes / 2**20:.1f} MiB, {now.fds} fds, {now.threads} thr{cpu}"
            )
        self.samples[minute] = figures
        self.previous = figures
        used, size = self.cell.state_usage()
        print(
            f"[{clock(minute * 60)}] " + "; ".join(parts) + f"; state dir {used / 2**20:.0f} of "
            f"{size / 2**20:.0f} MiB; load {load_average()}",
            flush=True,
        )

    async def minutes(self, stop: asyncio.Event) -> None:
        minute = 0
        while not stop.is_set():
            minute += 1
            wait = self.started + minute * 60 - time.time()
            try:
                await asyncio.wait_for(stop.wait(), max(0.0, wait))
                return
            except TimeoutError:
                pass
            await asyncio.to_thread(self.sample_minute, minute)

    def target(self, ok: bool, text: str) -> None:
        print(f"  target {verdict(ok)}: {text}")
        if not ok:
            self.failures.append(text)


def _metric(samples: dict[tuple[str, str], float], name: str, robot: str) -> float:
    return value_of(samples, "cobot_hmi_" + name, robot)


def print_frames(
    run: Run, soak: Soak, recordings: dict[str, Any], final: dict[tuple[str, str], float]
) -> None:
    print("frames (the recording: received = the service's seq of its last frame):")
    outside = 0
    deleted = value_of(final, "cobot_hmi_history_retention_deleted_segments_total") > 0
    for robot, rec in recordings.items():
        losses = recording_losses(
            rec, soak.faults, robot, started=run.started, retention_deleted=deleted
        )
        received, recorded = losses["received"], losses["recorded"]
        if losses["deleted"]:
            print(f"  {robot}: the first {losses['deleted']} frames deleted by retention")
        print(
            f"  {robot}: received {received}, recorded {recorded}, not recorded "
            f"{received - recorded} (/metrics: recorded "
            f"{_metric(final, 'history_frames_recorded_total', robot):.0f}, not recorded "
            f"{_metric(final, 'history_frames_not_recorded_total', robot):.0f}, recorder "
            f"queue dropped {_metric(final, 'history_frames_dropped_total', robot):.0f})"
        )
        print(f"    not recorded: {losses['recorder'].text()}")
        print(
            f"    lost on the wire: {losses['wire'].text()}; new connections: "
            f"{losses['restarts'].text()} (/metrics: gaps "
            f"{_metric(final, 'frame_gaps_total', robot):.0f}, connections lost "
            f"{_metric(final, 'connection_losses_total', robot):.0f})"
        )
        if losses["backwards"]:
            print(f"    seq went backwards {losses['backwards']}×")
        outside += losses["recorder"].frames[OUTSIDE]
        outside += losses["wire"].frames[OUTSIDE] + losses["backwards"]
        outside += losses["restarts"].frames[OUTSIDE]
        for heap in (losses["recorder"], losses["wire"], losses["restarts"]):
            for t in heap.outside_at[:5]:
                print(f"    outside faults at {run.at(t)}")
    ws = client_losses(soak.clients, soak.faults, soak.stall_robot, run.started)
    frames = sum(c.frames for group in soak.clients.values() for c in group)
    print(f"  WebSocket clients: {frames} frames read; missed {ws.text()}")
    for t in ws.outside_at[:5]:
        print(f"    a client missed frames outside faults at {run.at(t)}")
    outside += ws.frames[OUTSIDE]
    run.target(outside == 0, f"frames lost outside the injected faults: {outside}")


def print_writes(
    run: Run, soak: Soak, audit: list[dict[str, Any]], recordings: dict[str, Any]
) -> None:
    checked = check_writes(soak.writer.records, audit, recordings, soak.faults)
    print(
        f"writes: {checked['attempts']} attempts, {checked['confirmed']} confirmed; answers "
        + ", ".join(f"{s or 'none'}: {n}" for s, n in sorted(checked["by_status"].items()))
    )
    for reason, n in checked["reasons"].most_common(10):
        print(f"    {n}× {reason or '(no reason)'}")
    print(
        f"  audit: {checked['audit_rows']} write rows, "
        + ", ".join(f"{o} {n}" for o, n in checked["audit_outcomes"].most_common())
        + f"; confirmed in the audit but not to the writer: {checked['audited_not_told']}"
    )
    recorded = checked["confirmed"] - len(checked["not_recorded"]) - checked["unrecordable"]
    print(
        f"  confirmed and recorded: {recorded}; while the disk was full (not recordable): "
        f"{checked['unrecordable']}"
    )
    for w in (checked["not_audited"] + checked["not_recorded"])[:5]:
        print(f"    write {w.number} to {w.robot} ({w.pattern:#06x}) at {run.at(w.sent)}")
    applied = checked["applied_unconfirmed"]
    print(
        f"  not confirmed to the writer but applied (the recording shows its outputs): "
        f"{len(applied)}"
        + "".join(
            f"; write {w.number} to {w.robot} at {run.at(w.sent)} answered {w.status or 'none'}"
            f" ({w.reason})"
            for w in applied[:5]
        )
    )
    missing_audit, missing_rec = len(checked["not_audited"]), len(checked["not_recorded"])
    run.target(
        missing_audit == 0 and missing_rec == 0,
        f"confirmed writes missing from the audit: {missing_audit}, from the recording: "
        f"{missing_rec}",
    )


def print_alarms(
    run: Run,
    soak: Soak,
    rows: list[dict[str, Any]],
    current: list[dict[str, Any]],
    final: dict[tuple[str, str], float],
) -> None:
    """Raised vs cleared as the streams told them (the monitors see every event), beside the
    alarm history in the database: a transition it lacks could not be stored (while the disk
    was full; counted in ``alarm_write_errors_total``)."""
    stored = alarm_counts(rows)
    seen = stream_alarm_counts(soak.monitors)
    keys = sorted({(robot, key) for robot, key, _ in seen} | set(stored))
    print("alarms (raised, cleared on the streams; in brackets the alarm history's):")
    uneven = []
    for robot, key in keys:
        raised, cleared = seen[(robot, key, "activated")], seen[(robot, key, "cleared")]
        history = stored.get((robot, key), Counter())
        print(
            f"  {robot}:{key}: raised {raised}, cleared {cleared} "
            f"({history['activated']}, {history['cleared']})"
        )
        if raised != cleared:
            uneven.append(f"{robot}:{key}")
    errors = {
        r.name: value_of(final, "cobot_hmi_alarm_write_errors_total", r.name)
        for r in soak.cell.robots
    }
    print(
        "  alarm changes the service could not store: "
        + ", ".join(f"{robot} {n:.0f}" for robot, n in errors.items())
    )
    active = [a["id"] for a in current if a.get("active")]
    run.target(
        not uneven and not active,
        f"every alarm raised was cleared: uneven {uneven or 'none'}, active at the end "
        f"{active or 'none'}",
    )


def print_processes(run: Run) -> None:
    minutes = sorted(run.samples)
    if not minutes:
        return
    first = JUDGED_FROM_MINUTE if minutes[-1] > JUDGED_FROM_MINUTE else minutes[0]
    print(f"processes from minute {first} to the end (RSS, fds):")
    for role in run.samples[minutes[-1]]:
        base = run.samples.get(first, {}).get(role)
        later = [run.samples[m].get(role) for m in minutes if m >= first]
        if base is None or any(s is None or s[0] != base[0] for s in later):
            print(f"  {role}: restarted after minute {first}: not judged")
            continue
        figures = [s[1] for s in later if s is not None]
        rss = [f.rss_bytes / base[1].rss_bytes - 1 for f in figures]
        fds = [f.fds / base[1].fds - 1 for f in figures]
        # A count moves by whole descriptors (a connection opened or closed): at least ±1.
        fds_share = max(FLAT_SHARE, 1 / base[1].fds)
        flat = max(map(abs, rss)) <= FLAT_SHARE and max(map(abs, fds)) <= fds_share
        text = (
            f"{role}: RSS {base[1].rss_bytes / 2**20:.1f} → {figures[-1].rss_bytes / 2**20:.1f} "
            f"MiB ({min(rss) * 100:+.1f} … {max(rss) * 100:+.1f} %), fds {base[1].fds} → "
            f"{figures[-1].fds} ({min(fds) * 100:+.1f} … {max(fds) * 100:+.1f} %)"
        )
        if role in ("bench", "mosquitto"):
            print(f"  {text} (not ours: not judged)")
        else:
            run.target(flat, text + f" within ±{FLAT_SHARE * 100:g} % (fds: at least ±1)")


def print_mqtt(watcher: MqttWatcher, final: dict[tuple[str, str], float]) -> None:
    with watcher.lock:
        counts = dict(watcher.counts)
        historical = watcher.historical
    published = {
        labels: value
        for (name, labels), value in final.items()
        if name == "cobot_hmi_sparkplug_messages_total"
    }
    print(
        "Sparkplug B: the subscriber got "
        + ", ".join(f"{k} {v}" for k, v in sorted(counts.items()))
        + f" ({historical} historical DDATA); the service published "
        + ", ".join(f"{{{k}}} {v:.0f}" for k, v in sorted(published.items()))
    )


async def print_emulators(soak: Soak) -> None:
    """What each emulator says it sent (since its last start): T→O sent and dropped on
    purpose, and its pump's lateness (a robot that fell behind is no loss of the service's)."""
    for robot in soak.cell.robots:
        try:
            answer = await soak.http.get(robot.control_url + "/status")
            status = answer.json()
        except (httpx.HTTPError, ValueError) as error:
            print(f"emulator {robot.name}: no status ({error})")
            continue
        counters, pump = status.get("target_counters", {}), status.get("pump", {})
        print(
            f"emulator {robot.name} (start {robot.starts}): T→O sent "
            f"{counters.get('t2o_sent')}, dropped on purpose {counters.get('t2o_dropped')}; "
            f"pump: ring overflows {pump.get('ring_overflows')}, send errors "
            f"{pump.get('send_errors')}, latest late {pump.get('max_late_ns', 0) / 1e6:.1f} ms, "
            f"real-time {pump.get('realtime')}"
        )


def print_log(cell: Cell) -> None:
    log = cell.work / "logs" / "service.log"
    text = log.read_text(errors="replace") if log.exists() else ""
    errors = [line for line in text.splitlines() if "ERROR" in line or "Traceback" in line]
    print(f"service log: {len(errors)} lines with ERROR or Traceback ({log})")
    for line in errors[:5]:
        print(f"    {line[:200]}")
