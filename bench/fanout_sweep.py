"""``bench/fanout_sweep``: the fan-out benchmark (``bench/fanout``) at 1, 4, 8 and 16 robots, for
this commit and a baseline commit in the same run (issue 21).

Each robot count runs ``bench/fanout`` twice, the baseline's service first, then this one's (the
emulators and the clients are this commit's in both): RPI 10 ms, 16 WebSocket clients at full
rate spread over the robots' streams plus one that never reads, the recorder and the alarms on
(the service's defaults). The baseline is checked out in a git worktree with its extension
built in place (``--baseline-worktree``, made when missing). Printed: per robot count and
commit, the service's CPU per robot-frame with and without clients, the worst robot's cyclic
p99 ratio, T→O gaps; the target is ≤ 100 µs per robot-frame with clients at 16 robots, every
ratio ≤ 1.2, 0 gaps.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
TARGET_US: float = 100.0


@dataclass
class Figures:
    with_us: float
    without_us: float
    worst_ratio: float
    gaps: int
    lossless: bool


def baseline_source(commit: str, worktree: Path) -> Path:
    """The baseline's ``backend/src``, checked out and its extension built once."""
    if not worktree.exists():
        subprocess.run(
            ["git", "-C", str(ROOT), "worktree", "add", "--detach", str(worktree), commit],
            check=True,
        )
    backend = worktree / "backend"
    if not list((backend / "src/cobot_hmi/native").glob("_cyclic_pump*.so")):
        subprocess.run(
            [sys.executable, "setup.py", "build_ext", "--inplace"],
            cwd=backend,
            check=True,
            stdout=subprocess.DEVNULL,
        )
    return backend / "src"


def run_once(robots: int, args: argparse.Namespace, source: Path | None) -> Figures:
    command = [
        sys.executable,
        str(HERE / "fanout_bench.py"),
        "--robots",
        str(robots),
        "--clients",
        str(args.clients),
        "--seconds",
        str(args.seconds),
        "--baseline-seconds",
        str(args.baseline_seconds),
        "--cycles",
        str(args.cycles),
    ]
    if source is not None:
        command += ["--service-source", str(source)]
    done = subprocess.run(command, check=False, capture_output=True, text=True, cwd=HERE)
    out = done.stdout
    if args.verbose:
        print(out, done.stderr[-2000:], sep="\n")
    found = re.search(r"per robot-frame: with clients (\d+) µs .* without (\d+) µs", out)
    if found is None:
        raise SystemExit(f"bench/fanout failed ({done.returncode}):\n{out}\n{done.stderr[-3000:]}")
    ratios = [float(r) for r in re.findall(r"ratio ([0-9.]+|nan) \(target", out)]
    gaps = re.search(r"T→O gaps (\d+)", out)
    return Figures(
        float(found.group(1)),
        float(found.group(2)),
        max(ratios) if ratios else float("nan"),
        int(gaps.group(1)) if gaps else -1,
        "fast clients lose nothing: True" in out,
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", default="1,4,8,16", help="robot counts, comma-separated")
    parser.add_argument("--baseline", default="58f13a2", help="the commit to compare with")
    parser.add_argument("--baseline-worktree", type=Path, default=None)
    parser.add_argument("--clients", type=int, default=16)
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--baseline-seconds", type=float, default=20.0)
    parser.add_argument("--cycles", type=int, default=3)
    parser.add_argument("--verbose", action="store_true")
    args = parser.parse_args()
    worktree = args.baseline_worktree or ROOT.parent / f"cobot-hmi-bench-{args.baseline}"
    source = baseline_source(args.baseline, worktree)
    head = subprocess.run(
        ["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
        check=False,
        capture_output=True,
        text=True,
    ).stdout.strip()
    print(
        f"bench/fanout_sweep: RPI 10 ms, {args.clients} clients + 1 never reading, recorder and "
        f"alarms on; {args.cycles} alternations of {args.baseline_seconds / args.cycles:g} s "
        f"without and {args.seconds / args.cycles:g} s with clients; service CPU per "
        "robot-frame in µs"
    )
    heading = ("robots", "commit", "with", "without", "worst p99 ratio", "gaps")
    print("{:>6}  {:>8}  {:>6}  {:>7}  {:>15}  {}".format(*heading))
    verdict: bool | None = None  # measured only with 16 robots in the sweep
    for robots in (int(n) for n in args.robots.split(",")):
        for label, src in ((args.baseline, source), (head or "HEAD", None)):
            figures = run_once(robots, args, src)
            print(
                f"{robots:>6}  {label:>8}  {figures.with_us:>6.0f}  {figures.without_us:>7.0f}  "
                f"{figures.worst_ratio:>15.3f}  {figures.gaps}"
                + ("" if figures.lossless else "  (a fast client lost frames)"),
                flush=True,
            )
            if src is None and robots == 16:
                verdict = (
                    figures.with_us <= TARGET_US
                    and figures.worst_ratio <= 1.2
                    and figures.gaps == 0
                )
    print(
        f"  target at 16 robots: ≤ {TARGET_US:g} µs per robot-frame with clients, every ratio "
        f"≤ 1.2, 0 gaps: {'not measured' if verdict is None else verdict}   "
        f"(load average {os.getloadavg()[0]:.2f}, {os.cpu_count()} CPUs)"
    )
    return 0 if verdict is not False else 1


if __name__ == "__main__":
    raise SystemExit(main())
