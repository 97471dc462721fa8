"""Layer: emulator, pure robot model (no I/O, no sockets, no asyncio; imports the layout, the
codec and the generated frames only, never the target, the scanner or the service).

The simulated Doosan arm behind the emulator's EtherNet/IP target: kinematics, motion, monitoring
values, robot states and flags, I/O. ``SimulatedRobot`` is what the target reads and writes.
"""

from cobot_hmi.emulator.robot.models import MODELS, RobotModel, model_by_name
from cobot_hmi.emulator.robot.robot_io import IdleBehaviour
from cobot_hmi.emulator.robot.simulated import RobotSettings, SimulatedRobot
from cobot_hmi.emulator.robot.states import RobotCommandError, RobotStateConflict, StateTimings

__all__ = [
    "MODELS",
    "IdleBehaviour",
    "RobotCommandError",
    "RobotModel",
    "RobotSettings",
    "RobotStateConflict",
    "SimulatedRobot",
    "StateTimings",
    "model_by_name",
]
