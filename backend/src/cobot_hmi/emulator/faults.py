"""Layer: emulator. Imports nothing of the project.

Fault hooks the target honours on every T→O packet and Forward Open. The emulator's control
API (issue 4) sets them; tests set them directly. Plain mutable fields: the target reads them
each time, so a change takes effect on the next packet built. The control API also tells the
target at once; one set directly while T→O is a periodic stream of the pump waits for the class
1 engine's next wake-up (at the robot's next change of its own: up to its monitoring period).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class TargetFaults:
    t2o_drop_percent: float = 0.0
    """Share of T→O packets not sent (their sequence numbers are used up: the consumer sees
    gaps). Drawn from the target's seeded ``random.Random``."""
    t2o_delay_ms: float = 0.0
    """Extra delay before each T→O packet leaves."""
    t2o_silent: bool = False
    """Stop producing T→O entirely (the TCP session and the connection stay open)."""
    t2o_interval_factor: float = 1.0
    """T→O leaves every this many granted RPIs (the Forward Open reply still grants the RPI
    asked for): 5 makes a target that grants 2 ms and sends every 10 ms, as an adapter whose
    timer ticks slower than the RPIs it accepts. Its sequence numbers rise by one per packet
    sent: the originator sees no gap, only a slow target."""
    t2o_corrupt_count: int = 0
    """Corrupt the next N T→O packets (each sent malformed), counting down."""
    refuse_next_forward_open: int | None = None
    """Refuse the next Forward Open with this extended status (general status 0x01)."""

    def per_packet(self) -> bool:
        """Whether a fault decides packet by packet (so T→O cannot be a periodic stream)."""
        return bool(
            self.t2o_drop_percent
            or self.t2o_delay_ms
            or self.t2o_silent
            or self.t2o_corrupt_count
            or self.t2o_interval_factor != 1.0
        )

    def t2o_period_s(self, rpi_us: int) -> float:
        """How often T→O of a connection granted ``rpi_us`` leaves, in seconds."""
        return rpi_us * self.t2o_interval_factor / 1e6

    def reset(self) -> None:
        self.t2o_drop_percent = 0.0
        self.t2o_delay_ms = 0.0
        self.t2o_silent = False
        self.t2o_interval_factor = 1.0
        self.t2o_corrupt_count = 0
        self.refuse_next_forward_open = None
