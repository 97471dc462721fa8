"""Event loop timer benchmark (see bench/eventloop): how late ``loop.call_at`` fires in the
product's loop (``eventloop.precise_event_loop``: epoll with a timerfd per wait) against the two
stdlib loops it replaced or could have been, measured in the same run, in alternating rounds:

- ``SelectSelector``: what the product used before (microsecond timeouts, but ``select()``
  refuses any file descriptor above 1023);
- ``EpollSelector``: asyncio's default on Linux (no ceiling, timeouts rounded up to whole ms).

The product's loop also tightens its thread's timer slack to 1 µs; that stays for the thread,
so every loop of the run has it, and the comparison is the selectors'. Each loop runs a
drift-free periodic timer (``deadline += period``, as the class 1 owners
schedule their batches) and records how late each call ran after its deadline. Printed per
loop: p50, p99 and max lateness, the load average before and after (a busy machine's scheduling
shows in every loop alike; compare the loops with each other, not with another run).

Target: the product's loop is not later than ``SelectSelector`` at the median (within 50 µs)
and is clearly earlier than ``EpollSelector``'s rounding (its median lateness under half of
epoll's).
"""

from __future__ import annotations

import argparse
import asyncio
import os
import selectors
import statistics
from collections.abc import Callable

from cobot_hmi.eventloop import precise_event_loop

LoopFactory = Callable[[], asyncio.AbstractEventLoop]


def _stdlib(selector: type[selectors.BaseSelector]) -> LoopFactory:
    return lambda: asyncio.SelectorEventLoop(selector())


LOOPS: dict[str, LoopFactory] = {
    "product (epoll + timerfd)": precise_event_loop,
    "SelectSelector (before)": _stdlib(selectors.SelectSelector),
    "EpollSelector (asyncio default)": _stdlib(selectors.EpollSelector),
}


async def _lateness(period_s: float, count: int) -> list[float]:
    loop = asyncio.get_running_loop()
    done = loop.create_future()
    late_s: list[float] = []
    deadline = loop.time() + period_s

    def tick() -> None:
        nonlocal deadline
        late_s.append(loop.time() - deadline)
        if len(late_s) == count:
            done.set_result(None)
            return
        deadline += period_s
        loop.call_at(deadline, tick)

    loop.call_at(deadline, tick)
    await done
    return late_s


def _percentile(values: list[float], fraction: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(fraction * len(ordered)))]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--period-ms", type=float, default=2.0)
    parser.add_argument("--timers", type=int, default=1000, help="timer calls per round")
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    period_s = args.period_ms / 1e3
    load_before = " ".join(f"{v:.2f}" for v in os.getloadavg())
    results: dict[str, list[float]] = {name: [] for name in LOOPS}
    for _ in range(args.rounds):
        for name, factory in LOOPS.items():
            with asyncio.Runner(loop_factory=factory) as runner:
                results[name] += runner.run(_lateness(period_s, args.timers))
    load_after = " ".join(f"{v:.2f}" for v in os.getloadavg())
    print(
        f"bench/eventloop: a periodic timer every {args.period_ms} ms, {args.timers} calls per "
        f"loop and round, {args.rounds} alternating rounds; load average {load_before} before, "
        f"{load_after} after"
    )
    medians: dict[str, float] = {}
    for name, late_s in results.items():
        medians[name] = statistics.median(late_s)
        print(
            f"  {name:32} late p50 {medians[name] * 1e3:6.3f} ms  "
            f"p99 {_percentile(late_s, 0.99) * 1e3:6.3f} ms  max {max(late_s) * 1e3:6.3f} ms"
        )
    product, before, default = medians.values()
    as_select = product <= before + 50e-6
    beats_epoll = product < default / 2
    print(
        f"  targets: median within 50 µs of SelectSelector {'MET' if as_select else 'MISSED'}; "
        f"under half of EpollSelector's {'MET' if beats_epoll else 'MISSED'}"
    )


if __name__ == "__main__":
    main()
