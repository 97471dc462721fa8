"""Layer: health (pure: arrays in, figures out; no I/O, no threads, no clock of its own).
Imports the layout, the codec's ``Frame``, ``arms`` and ``stored_format``; never the service,
the emulator or the scanner.

Robot health (issue 40, docs/health.md): each joint's torque signature per cycle, friction,
reducer life used, heat and knocks, and the robot's cycle-time drift, measured against the
robot's own healthy baseline, with a verdict per joint (ok / watch / act) and its reason in a
sentence. ``HealthEngine`` is the one object a consumer holds per robot: frames in
(``FrameBlock``), cycle boundaries in (``end_cycle``), figures out (``report``), and its whole
state as a versioned JSON document (``to_document`` / ``from_document``). One concern per
module: ``frames`` (the arrays), ``samples`` (the distinct measurements among them),
``health_settings`` (thresholds), ``friction``, ``signature``,
``heat``, ``life``, ``knocks``, ``drift``, ``baseline``, ``verdict``, ``report`` (the
figures and the state's body), ``document``, ``engine``.
"""

from cobot_hmi.health.engine import HealthEngine
from cobot_hmi.health.frames import FrameBlock
from cobot_hmi.health.health_settings import HealthSettings

__all__ = ["FrameBlock", "HealthEngine", "HealthSettings"]
