"""Layer: emulator. Imports the codec and the history storage's recording reader.

A robot that plays a recording back (``cobot-hmi emulator --replay FILE``): the T→O frame at
each instant is the recorded frame of the same offset from the recording's start (times
``speed``), so an incident re-runs against the HMI over the real protocol, at the connection's
RPI whatever rate it was recorded at. After the last frame it holds it, or with ``loop`` starts
again. Commands are taken and answered as the O→T image (explicit reads) but change nothing:
the outputs are what was recorded.

No recorded frame is skipped that a packet could carry: each packet carries the frame its
instant is due, but never more than one frame past the previous packet's. A recording's
receive times jitter around its RPI, so a clock-only choice at the same RPI would drop one
frame and send its neighbour twice wherever two receive times fall between two packets; here
the replay falls a little behind instead and stays in order. Only when it is more than
``max_lag_s`` behind (a connection slower than the recording's frames, a stalled event loop)
does it jump to the instant's frame, and counts what it left out (``frames_skipped``).
"""

from __future__ import annotations

import numpy as np

from cobot_hmi.codec import CommandImage, Frame, decode_frame, zero_command
from cobot_hmi.history.recording import Recording

MAX_LAG_S = 1.0
"""How far (wall seconds) the replay may fall behind the recording's clock to send every
frame in order; past that it catches up by skipping. A second keeps an incident's timing
readable against the HMI's events while no short stall of a busy machine drops a frame."""


class ReplayRobot:
    """A :class:`~cobot_hmi.emulator.process_image.ProcessImage` replaying ``recording``."""

    def __init__(
        self,
        recording: Recording,
        *,
        speed: float = 1.0,
        loop: bool = False,
        start_s: float | None = None,
        max_lag_s: float = MAX_LAG_S,
    ) -> None:
        """``start_s``: when the first frame plays (None: at the first call)."""
        if not speed > 0:
            raise ValueError("speed must be above 0")
        if not max_lag_s >= 0:
            raise ValueError("max_lag_s must be 0 or more")
        self.recording = recording
        self.speed = speed
        self.loop = loop
        self.max_lag_s = max_lag_s
        self._offsets_s = recording.time_s - recording.time_s[0]
        last_interval = float(np.median(np.diff(self._offsets_s))) if len(recording) > 1 else 0.0
        # One period longer than the last frame's offset: the last frame plays its own time too.
        self._duration_s = float(self._offsets_s[-1]) + max(last_interval, 0.0)
        self._cycles = loop and self._duration_s > 0
        self._start_s = start_s
        self._position = -1
        """The frame last produced, counted across passes: pass × len(recording) + index."""
        self._frame: Frame | None = None
        self._command = zero_command()
        self.commands_consumed = 0
        self.frames_played = 0
        """Recorded frames sent, each counted once (a held frame is not counted again)."""
        self.frames_skipped = 0
        """Recorded frames left out to catch up (more than ``max_lag_s`` behind)."""

    @property
    def data_period_s(self) -> float:
        return 0.0  # every instant may be another recorded frame

    @property
    def loops(self) -> int:
        """Times the recording started again (``loop``)."""
        return max(self._position, 0) // len(self.recording)

    def _recording_offset_s(self, now_s: float) -> float:
        if self._start_s is None:
            self._start_s = now_s
        return max(0.0, (now_s - self._start_s) * self.speed)

    def _due_position(self, offset_s: float) -> int:
        """The frame due at ``offset_s`` of recording time, counted across passes."""
        passes = 0
        if self._cycles:
            passes = int(offset_s // self._duration_s)
            offset_s -= passes * self._duration_s
        index = int(np.searchsorted(self._offsets_s, offset_s, side="right")) - 1
        return passes * len(self.recording) + max(0, min(index, len(self.recording) - 1))

    def _offset_of(self, position: int) -> float:
        passes, index = divmod(position, len(self.recording))
        return passes * self._duration_s + float(self._offsets_s[index])

    def index_at(self, now_s: float) -> int:
        """The recorded frame whose instant ``now_s`` is, by the clock alone."""
        return self._due_position(self._recording_offset_s(now_s)) % len(self.recording)

    def produce_frame(self, now_s: float) -> Frame:
        offset_s = self._recording_offset_s(now_s)
        due = self._due_position(offset_s)
        position = self._position
        if due > position:
            following = position + 1
            behind_s = (offset_s - self._offset_of(following)) / self.speed
            if due == following or behind_s <= self.max_lag_s:
                position = following
            else:
                self.frames_skipped += due - following
                position = due
            self.frames_played += 1
        if position != self._position or self._frame is None:
            index = position % len(self.recording)
            # The same object while the frame holds: the target encodes it once.
            self._frame = decode_frame(self.recording.raw[index].tobytes())
            self._position = position
        return self._frame

    def summary(self) -> str:
        """What the replay did, in words (the emulator prints it when it stops)."""
        return (
            f"replay: {self.frames_played} recorded frames sent, {self.frames_skipped} skipped "
            f"(over {self.max_lag_s:g} s behind), {self.loops} loops"
        )

    def consume_command(self, image: CommandImage, now_s: float) -> None:
        self.commands_consumed += 1
        self._command = image

    def outputs_idle(self, now_s: float) -> None:
        pass

    def command_image(self) -> CommandImage:
        return self._command
