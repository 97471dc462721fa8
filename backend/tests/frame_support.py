"""A test's own consumer of a robot's frames: registered like every other consumer
(``FrameNotifier.add``), on a thread of its own (the test's), taking what was queued when the
test asks."""

from __future__ import annotations

from collections.abc import Sequence

from cobot_hmi.service.robots.frame_notifier import FrameNotifier, FrameRecord, Runs


class CollectedFrames:
    """Every frame of one robot from now on, in a bounded queue the test drains with ``take``."""

    runs = Runs.THREAD

    def __init__(self, notifier: FrameNotifier, queue_frames: int, name: str = "test") -> None:
        self.name = name
        self.queue_frames = queue_frames
        self._notifier = notifier
        self.records: list[FrameRecord] = []
        """Every frame received so far (``take`` and ``seen`` fetch what is queued first)."""
        self._taken = 0
        self.registration = notifier.add(self)

    def on_frames(self, robot: str, records: Sequence[FrameRecord]) -> None:
        self.records.extend(records)

    def take(self) -> list[FrameRecord]:
        """The frames received since the last ``take``, oldest first."""
        self.registration.deliver()
        taken = self.records[self._taken :]
        self._taken = len(self.records)
        return taken

    def seen(self) -> list[FrameRecord]:
        """Every frame received so far, oldest first."""
        self.registration.deliver()
        return list(self.records)

    @property
    def dropped(self) -> int:
        return self.registration.dropped

    def close(self) -> None:
        self._notifier.remove(self.registration)
