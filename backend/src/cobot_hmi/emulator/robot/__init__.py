"""Layer: emulator, pure robot model (no I/O, no sockets, no asyncio). Imports the layout, the
codec, the generated frames and the target's pure ``process_image`` types; never the target
itself, the scanner or the service.

The simulated Doosan arm behind the emulator's EtherNet/IP target: kinematics, motion, monitoring
values, robot states and flags, I/O. ``SimulatedRobot`` is what the target reads and writes.
"""

from cobot_hmi.emulator.process_image import IdleBehaviour
from cobot_hmi.emulator.robot.models import MODELS, RobotModel, model_by_name
from cobot_hmi.emulator.robot.simulated import RobotSettings, SimulatedRobot
from cobot_hmi.emulator.robot.states import RobotCommandError, RobotStateConflictError, StateTimings

__all__ = [
    "MODELS",
    "IdleBehaviour",
    "RobotCommandError",
    "RobotModel",
    "RobotSettings",
    "RobotStateConflictError",
    "SimulatedRobot",
    "StateTimings",
    "model_by_name",
]
