"""Layer: history storage. Imports only ``segments`` and ``stored_format``'s error.

A closed journal becomes its segment in a short-lived process of its own
(``close_in_child``; the child is ``python -m cobot_hmi.history.close_process``), so the memory
the conversion takes is handed back to the system when the child exits. In the service's own
process, the allocators kept what a conversion had freed for reuse: the Parquet writer's tables,
Arrow's mimalloc pages, glibc's heap. That showed as a lasting step of the service's RSS at the
first segment close (about +9 % in ``bench/soak``'s hour) that neither Arrow's
``release_unused`` nor ``malloc_trim`` took back. The child costs about 0.2 s of imports (pyarrow
and numpy, not the service) once per segment (every ten minutes per robot by default).

The child runs in a session of its own, so a Ctrl-C in the terminal stops the service (which
waits for the conversion under way) but not the conversion half way; and it dies with the
thread that started it (``PR_SET_PDEATHSIG``): a service killed with ``kill -9`` leaves no
conversion running beside the next start's recovery of the same journal. A conversion cut short
leaves only a temporary file and the journal, which the next conversion uses
(``segments.close_journal``).

The child answers with one JSON line on its standard output: ``{"segment": null}`` (the journal
held no complete frame), ``{"segment": {"path", "start_us", "end_us"}}``, or
``{"error": reason}`` for a conversion that failed (a full disk, a journal it could not read),
``{"refused": reason}`` for a journal of a newer format than this build reads (left as it is).
"""

from __future__ import annotations

import argparse
import ctypes
import json
import os
import signal
import subprocess
import sys
from pathlib import Path
from typing import Final

import pyarrow as pa

from cobot_hmi.history import segments
from cobot_hmi.history.segments import Segment
from cobot_hmi.stored_format import FormatVersionError

_PR_SET_PDEATHSIG: Final = 1
"""prctl(2): the signal a process gets when the thread that started it ends."""

REASON_CHARS: Final = 500
"""The most of a child's error output kept in a reason (its last characters)."""


class JournalCloseError(Exception):
    """The conversion failed; ``reason`` says why (the journal is kept, to be tried again)."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


class JournalRefusedError(JournalCloseError):
    """The journal is of a newer format than this build reads: kept as it is, never tried
    again by this process (``reason`` names it and its version)."""


def close_in_child(path: Path, robot: str) -> Segment | None:
    """Turn the closed journal ``path`` of ``robot`` into its segment in a child process and
    wait for it (seconds for ten minutes at RPI 2 ms: call it off the event loop). ``None``: the
    journal held no complete frame. Raises ``JournalCloseError`` with the reason when it failed."""
    command = [
        sys.executable,
        "-m",
        __name__,
        "--parent-pid",
        str(os.getpid()),
        str(path),
        robot,
    ]
    done = subprocess.run(
        command, check=False, capture_output=True, text=True, start_new_session=True
    )
    answer: dict[str, object] | None = None
    lines = done.stdout.strip().splitlines()
    if lines:
        try:
            parsed = json.loads(lines[-1])
        except ValueError:
            parsed = None
        if isinstance(parsed, dict):
            answer = parsed
    if answer is None or (done.returncode != 0 and not {"error", "refused"} & answer.keys()):
        raise JournalCloseError(_failure_words(done))
    if "refused" in answer:
        raise JournalRefusedError(str(answer["refused"]))
    if "error" in answer:
        raise JournalCloseError(str(answer["error"]))
    made = answer.get("segment")
    if made is None:
        return None
    if not isinstance(made, dict):
        raise JournalCloseError(f"the closing process answered {lines[-1]!r}")
    return Segment(
        robot=robot,
        path=Path(str(made["path"])),
        start_us=int(made["start_us"]),
        end_us=int(made["end_us"]),
    )


def _failure_words(done: subprocess.CompletedProcess[str]) -> str:
    if done.returncode < 0:
        try:
            name = signal.Signals(-done.returncode).name
        except ValueError:
            name = f"signal {-done.returncode}"
        ended = f"the closing process was ended by {name}"
    else:
        ended = f"the closing process exited with {done.returncode}"
    said = done.stderr.strip()[-REASON_CHARS:]
    return f"{ended}: {said}" if said else ended


def _die_with_parent(parent_pid: int) -> None:
    """Ask the kernel for SIGKILL when the starting thread ends, then make sure it has not
    ended already (before the request was made)."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    except (OSError, AttributeError):
        pass  # no prctl (not Linux): a parent gone before this start is still seen below
    if os.getppid() != parent_pid:
        sys.exit(3)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[1])
    parser.add_argument("--parent-pid", type=int, required=True)
    parser.add_argument("journal", type=Path)
    parser.add_argument("robot")
    args = parser.parse_args(argv)
    _die_with_parent(args.parent_pid)
    try:
        segment = segments.close_journal(args.journal, args.robot)
    except OSError as error:
        print(json.dumps({"error": error.strerror or str(error)}), flush=True)
        return 1
    except pa.ArrowException as error:
        print(json.dumps({"error": str(error)}), flush=True)
        return 1
    except FormatVersionError as error:
        print(json.dumps({"refused": str(error)}), flush=True)
        return 1
    made = (
        None
        if segment is None
        else {"path": str(segment.path), "start_us": segment.start_us, "end_us": segment.end_us}
    )
    print(json.dumps({"segment": made}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
