"""The OPC UA updater reads a frame binding only when its field changed (``FieldReads``,
opcua/values.py): for a moving robot's frames, the bindings it reads and finds changed are
exactly those that reading every binding finds changed, in the same order."""

from __future__ import annotations

from asyncua import ua

from cobot_hmi.codec import Frame, decode_frame, encode_frame
from cobot_hmi.emulator.robot import RobotSettings, SimulatedRobot
from cobot_hmi.layout import T2O_FIELDS
from cobot_hmi.opcua import layout_nodes
from cobot_hmi.opcua.bindings import Binding
from cobot_hmi.opcua.robotics import emergency_stop, protective_stop
from cobot_hmi.opcua.values import FieldReads


def _bindings() -> list[Binding]:
    """One binding per element of every T→O field as the layout's builder makes them, and a
    few that read any field (as the Robotics builder's safety values)."""
    bindings: list[Binding] = []
    for field in T2O_FIELDS:
        position = Frame._fields.index(field.name)
        for index in [None] if field.scalar else range(field.count):
            read = layout_nodes._element(position, index)
            node = ua.NodeId(f"{field.name}.{index}", 2)
            bindings.append(Binding(node, read, ua.VariantType.Variant, position))
        if len(bindings) % 7 == 0:
            any_field = ua.NodeId(len(bindings), 3)
            bindings.append(Binding(any_field, emergency_stop, ua.VariantType.Boolean))
    bindings.append(Binding(ua.NodeId("protective", 3), protective_stop, ua.VariantType.Boolean))
    return bindings


def _frames() -> list[Frame]:
    """A moving robot's frames at 100 Hz for 3 s (its monitoring refreshed every 100 ms: most
    repeat), each also as a copy decoded from its bytes (equal fields, another object)."""
    robot = SimulatedRobot(RobotSettings(kinematic_refresh_ms=100.0), start_s=0.0)
    frames: list[Frame] = []
    for k in range(300):
        frame = robot.produce_frame(k / 100)
        frames.append(frame)
        if k % 3 == 0:
            frames.append(decode_frame(encode_frame(frame)))
    return frames


def test_only_the_changed_fields_bindings_are_read_and_they_are_all_that_changed() -> None:
    bindings, frames = _bindings(), _frames()
    reading = FieldReads(bindings)
    assert reading.indices(frames[0]) is None  # the first frame: every binding
    all_changes: list[list[int]] = []
    chosen_changes: list[list[int]] = []
    kept_all = [b.read(frames[0]) for b in bindings]
    kept_chosen = list(kept_all)
    read_counts = []
    for frame in frames[1:]:
        fresh = [b.read(frame) for b in bindings]
        changed = [i for i, new in enumerate(fresh) if new != kept_all[i]]
        for i in changed:
            kept_all[i] = fresh[i]
        all_changes.append(changed)
        only = reading.indices(frame)
        assert only is not None and only == sorted(only)
        read_counts.append(len(only))
        found = [i for i in only if bindings[i].read(frame) != kept_chosen[i]]
        for i in found:
            kept_chosen[i] = bindings[i].read(frame)
        chosen_changes.append(found)
    assert chosen_changes == all_changes
    assert kept_chosen == kept_all
    assert any(all_changes), "the robot moved"
    assert sum(read_counts) < len(bindings) * len(read_counts) / 2, "most fields kept theirs"


def test_everything_reads_every_binding_again() -> None:
    bindings = _bindings()
    reading = FieldReads(bindings)
    frame = _frames()[0]
    reading.indices(frame)
    assert reading.indices(frame, everything=True) is None
    always = [i for i, b in enumerate(bindings) if b.field_position is None]
    assert reading.indices(frame) == always  # the same frame again: only what reads any field
