"""Layer: history storage. Imports only ``segments``, ``close_process`` and ``stored_format``'s
error.

Journals closed by the recorder become segments here, one at a time in the order handed over
(``JournalCloser.submit``), each in a short-lived process of its own started and waited for by
a thread of the closer's (``close_process``: the memory a conversion takes goes back to the
system with the process). Closing a ten-minute journal of a
robot at RPI 2 ms (300,000 frames) takes seconds of a busy machine; done on the recorder's
thread it held every robot's frames in their queues meanwhile (frames dropped when they
overflowed), and after a full disk it held the resumption back until the old journal was
converted. Now the recorder hands the journal over and records on in a new one at once.

A closed journal stays a journal on disk until its segment is complete (a query reads it as
the journal until then, ``query._sources``), so nothing recorded is out of reach or lost
meanwhile; a crash leaves it for the next start. A conversion that fails (a full disk) is
tried again every ``retry_s``, the journal kept. A journal of a newer format than this build
reads (``formats``) is left on disk as it is, said once, and not tried again.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from pathlib import Path

from cobot_hmi.history.close_process import JournalCloseError, JournalRefusedError, close_in_child
from cobot_hmi.history.segments import Segment
from cobot_hmi.stored_format import FormatVersionError

log = logging.getLogger(__name__)


class JournalCloser:
    """``start``, ``submit`` journals, ``stop`` (converting what is left, once each).
    ``on_closed(robot, segment)`` runs on the closer's thread after each conversion
    (``segment`` ``None``: the journal held no complete frame)."""

    def __init__(
        self,
        *,
        retry_s: float,
        on_closed: Callable[[str, Segment | None], None] | None = None,
        convert: Callable[[Path, str], Segment | None] = close_in_child,
    ) -> None:
        self.retry_s = retry_s
        self.on_closed = on_closed
        self._convert_journal = convert
        """How a journal becomes its segment: in a child process (``close_process``); a
        benchmark's baseline converts in its own process."""
        self.errors = 0
        """Conversions that failed (each tried again)."""
        self.refused = 0
        """Journals of a newer format, left on disk as they are."""
        self.last_error: str | None = None
        self._jobs: list[tuple[str, Path]] = []
        self._busy: tuple[str, Path] | None = None
        self._condition = threading.Condition()
        self._stopping = False
        self._thread: threading.Thread | None = None

    @property
    def pending(self) -> int:
        """Journals waiting or being converted."""
        with self._condition:
            return len(self._jobs) + (self._busy is not None)

    def start(self) -> None:
        """Start the thread."""
        self._stopping = False
        self._thread = threading.Thread(target=self._run, name="history closer", daemon=True)
        self._thread.start()

    def submit(self, robot: str, path: Path) -> None:
        """Convert ``path`` (a closed journal of ``robot``) when the ones before it are done;
        a journal already waiting or being converted is not taken twice."""
        job = (robot, path)
        with self._condition:
            if job == self._busy or job in self._jobs:
                return
            self._jobs.append(job)
            self._condition.notify()

    def stop(self) -> None:
        """Convert what is waiting (one attempt each: what fails stays a journal, for the
        next start), then end the thread. Blocks: call it off the event loop."""
        with self._condition:
            self._stopping = True
            self._condition.notify()
        thread = self._thread
        if thread is not None:
            thread.join()
        self._thread = None

    def wait_idle(self, timeout_s: float) -> bool:
        """Wait until nothing is waiting or being converted (tests, benchmarks)."""
        with self._condition:
            return self._condition.wait_for(
                lambda: not self._jobs and self._busy is None, timeout_s
            )

    def _run(self) -> None:
        while True:
            with self._condition:
                self._condition.wait_for(lambda: self._jobs or self._stopping)
                if not self._jobs:
                    return  # stopping, nothing left
                self._busy = job = self._jobs.pop(0)
            done = self._convert(*job)
            with self._condition:
                self._busy = None
                if not done:
                    if self._stopping:
                        continue  # left for the next start
                    self._jobs.insert(0, job)
                    self._condition.wait_for(lambda: self._stopping, self.retry_s)
                self._condition.notify_all()

    def _convert(self, robot: str, path: Path) -> bool:
        if not path.exists():
            return True  # closed meanwhile (``segments.recover``)
        try:
            segment = self._convert_journal(path, robot)
        except (JournalRefusedError, FormatVersionError) as error:
            # In a child (``close_in_child``) or in this process (a benchmark's baseline).
            self.refused += 1
            self.last_error = str(error)
            log.error("history of %s: journal left as it is: %s", robot, error)
            return True
        except (OSError, JournalCloseError) as error:
            # OSError: the closing process could not be started (no memory, no processes left).
            self.errors += 1
            reason = error.reason if isinstance(error, JournalCloseError) else error.strerror
            self.last_error = f"{path.name}: {reason or error}"
            log.warning("history of %s: journal not closed yet: %s", robot, self.last_error)
            return False
        if self.on_closed is not None:
            try:
                self.on_closed(robot, segment)
            except Exception:
                log.exception("history closer callback failed")
        return True
