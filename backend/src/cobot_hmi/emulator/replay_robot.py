"""Layer: emulator. Imports the codec and the history storage's recording reader.

A robot that plays a recording back (``cobot-hmi emulator --replay FILE``): the T→O frame at
each instant is the recorded frame of the same offset from the recording's start (times
``speed``), so an incident re-runs against the HMI over the real protocol, at the connection's
RPI whatever rate it was recorded at. After the last frame it holds it, or with ``loop`` starts
again. Commands are taken and answered as the O→T image (explicit reads) but change nothing:
the outputs are what was recorded.
"""

from __future__ import annotations

import numpy as np

from cobot_hmi.codec import CommandImage, Frame, decode_frame, zero_command
from cobot_hmi.history.recording import Recording


class ReplayRobot:
    """A :class:`~cobot_hmi.emulator.process_image.ProcessImage` replaying ``recording``."""

    def __init__(
        self,
        recording: Recording,
        *,
        speed: float = 1.0,
        loop: bool = False,
        start_s: float | None = None,
    ) -> None:
        """``start_s``: when the first frame plays (None: at the first call)."""
        if not speed > 0:
            raise ValueError("speed must be above 0")
        self.recording = recording
        self.speed = speed
        self.loop = loop
        self._offsets_s = recording.time_s - recording.time_s[0]
        last_interval = float(np.median(np.diff(self._offsets_s))) if len(recording) > 1 else 0.0
        # One period longer than the last frame's offset: the last frame plays its own time too.
        self._duration_s = float(self._offsets_s[-1]) + max(last_interval, 0.0)
        self._start_s = start_s
        self._index = -1
        self._frame: Frame | None = None
        self._command = zero_command()
        self.commands_consumed = 0
        self.loops = 0
        """Times the recording started again (``loop``)."""

    @property
    def data_period_s(self) -> float:
        return 0.0  # every instant may be another recorded frame

    def index_at(self, now_s: float) -> int:
        """The recorded frame playing at ``now_s``."""
        if self._start_s is None:
            self._start_s = now_s
        offset = max(0.0, (now_s - self._start_s) * self.speed)
        if self.loop and self._duration_s > 0:
            self.loops = int(offset // self._duration_s)
            offset %= self._duration_s
        index = int(np.searchsorted(self._offsets_s, offset, side="right")) - 1
        return max(0, min(index, len(self.recording) - 1))

    def produce_frame(self, now_s: float) -> Frame:
        index = self.index_at(now_s)
        if index != self._index or self._frame is None:
            # The same object while the frame holds: the target encodes it once.
            self._frame = decode_frame(self.recording.raw[index].tobytes())
            self._index = index
        return self._frame

    def consume_command(self, image: CommandImage, now_s: float) -> None:
        self.commands_consumed += 1
        self._command = image

    def outputs_idle(self, now_s: float) -> None:
        pass

    def command_image(self) -> CommandImage:
        return self._command
