"""Benchmark of issue 5 (``bench/write_latency``): PATCH /api/v1/command, request to confirmed.

The emulator and the service run as their own processes on fresh loopback addresses. One
operator takes control and sends N writes one after another, each flipping a ControlBox digital
output, so each answer waits for the robot's own T→O frame to show the new value (the path a
user's click takes: HTTP, audit row committed, O→T image, the robot applying it, its next
frame, the audit outcome committed). Printed: p50 / p95 / max beside the RPI, the service's own
figure (``latency_ms``), and a few bit-input-register writes (confirmed when the O→T packet
went out). Target: p95 ≤ 2 RPI + 10 ms.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import statistics
import time
from typing import Any

import httpx
from service_bench_support import BENCH_USER, stack


def percentile(values: list[float], share: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(len(ordered) * share))]


async def patch(client: httpx.AsyncClient, body: object, notes: list[str]) -> httpx.Response:
    """One write; if control was lost (the connection dropped on a busy machine), note it,
    wait for the connection, take control again and retry once."""
    answer = await client.patch("/api/v1/command", json=body)
    if answer.status_code == 409:
        notes.append(answer.json()["detail"]["reason"])
        for _ in range(100):
            if (await client.get("/readyz")).status_code == 200:
                break
            await asyncio.sleep(0.1)
        (await client.post("/api/v1/control/take")).raise_for_status()
        answer = await client.patch("/api/v1/command", json=body)
    if answer.status_code != 200:
        raise SystemExit(f"write {body}: {answer.status_code} {answer.text}")
    return answer


async def run(base_url: str, writes: int, register_writes: int) -> dict[str, list[Any]]:
    out: dict[str, list[Any]] = {
        "client_ms": [],
        "service_ms": [],
        "register_ms": [],
        "http_ms": [],
        "notes": [],
    }
    async with httpx.AsyncClient(base_url=base_url, timeout=10.0) as client:
        login = await client.post(
            "/api/v1/auth/login",
            json={"username": BENCH_USER[0], "password": BENCH_USER[1]},
        )
        login.raise_for_status()
        # A script authenticates with its token (the session cookie alone is for the HMI's own
        # pages: docs/operations.md "Security").
        client.headers["Authorization"] = f"Bearer {login.json()['token']}"
        (await client.post("/api/v1/control/take")).raise_for_status()
        for _ in range(5):  # warm-up: connections, code paths
            await patch(client, {"controlbox_do": {"0": True}}, out["notes"])
        for _ in range(50):  # the HTTP round trip alone, for comparison
            started = time.perf_counter()
            (await client.get("/api/v1/command")).raise_for_status()
            out["http_ms"].append((time.perf_counter() - started) * 1000)
        for i in range(writes):
            body = {"controlbox_do": {str(i % 16): bool((i // 16) % 2 == 0)}}
            started = time.perf_counter()
            answer = await patch(client, body, out["notes"])
            out["client_ms"].append((time.perf_counter() - started) * 1000)
            out["service_ms"].append(answer.json()["latency_ms"])
        for i in range(register_writes):
            body = {"bit_input_registers": {str(i % 64): i % 2 == 0}}
            started = time.perf_counter()
            await patch(client, body, out["notes"])
            out["register_ms"].append((time.perf_counter() - started) * 1000)
        await client.post("/api/v1/control/release")
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rpi-ms", type=float, default=10.0)
    parser.add_argument("--writes", type=int, default=200)
    parser.add_argument("--register-writes", type=int, default=50)
    parser.add_argument(
        "--robot-niceness",
        type=int,
        default=-10,
        help="nice value of the emulator (a real robot is its own machine; 0: same as the rest)",
    )
    args = parser.parse_args()

    with stack(args.rpi_ms, robot_niceness=args.robot_niceness) as running:
        figures = asyncio.run(run(running.base_url, args.writes, args.register_writes))

    target_ms = 2 * args.rpi_ms + 10
    client = figures["client_ms"]
    p95 = percentile(client, 0.95)
    print(
        f"bench/write_latency: {len(client)} confirmed writes at RPI {args.rpi_ms:g} ms "
        f"(emulator at nice {args.robot_niceness})"
    )
    print(
        f"  request → confirmed (client): p50 {percentile(client, 0.50):6.2f} ms  "
        f"p95 {p95:6.2f} ms  max {max(client):6.2f} ms  mean {statistics.fmean(client):6.2f} ms"
    )
    service = figures["service_ms"]
    print(
        f"  inside the service:           p50 {percentile(service, 0.50):6.2f} ms  "
        f"p95 {percentile(service, 0.95):6.2f} ms  max {max(service):6.2f} ms"
    )
    registers = figures["register_ms"]
    if registers:
        print(
            f"  bit input registers ({len(registers)}, O→T sent): "
            f"p50 {percentile(registers, 0.50):6.2f} ms  p95 {percentile(registers, 0.95):6.2f} ms"
        )
    http = figures["http_ms"]
    print(
        f"  HTTP round trip alone (GET /api/v1/command): p50 {percentile(http, 0.5):6.2f} ms  "
        f"p95 {percentile(http, 0.95):6.2f} ms"
    )
    for note in figures["notes"]:
        print(f"  note: control lost and taken again: {note}")
    print(f"  load average at the end: {os.getloadavg()[0]:.2f} (on {os.cpu_count()} CPUs)")
    print(f"  RPI {args.rpi_ms:g} ms; target p95 ≤ 2 RPI + 10 ms = {target_ms:g} ms")
    verdict = "met" if p95 <= target_ms else "NOT met"
    print(f"  target {verdict}: p95 {p95:.2f} ms vs {target_ms:g} ms")
    return 0 if p95 <= target_ms else 1


if __name__ == "__main__":
    raise SystemExit(main())
