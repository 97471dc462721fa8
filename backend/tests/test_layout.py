"""The layout table itself: sizes, no overlaps, every spec name once, the state enum, codegen."""

from __future__ import annotations

import json
from importlib import resources

import pytest

from cobot_hmi import codegen
from cobot_hmi.generated.frames import RobotState
from cobot_hmi.layout import (
    ASSEMBLIES,
    O2T_ASSEMBLY,
    ROBOT_STATES,
    T2O_ASSEMBLY,
    Assembly,
    flag_fields,
    robot_state_name,
)
from golden_vectors import STATE_NAMES

# The I/O table's canonical names (docs/assembly.md), transcribed independently.
SPEC_T2O_NAMES = """controlbox_di controlbox_do analog_input_type analog_output_type analog_input
analog_output tool_di tool_do controller_version robot_state servo_on safety_stopped
emergency_stopped direct_teach_button_pressed power_button_pressed joint_position joint_velocity
joint_motor_current joint_motor_temperature joint_torque joint_external_torque tcp_position
tcp_orientation tcp_velocity tcp_angular_velocity tool_offset_position tool_offset_orientation
external_force external_moment bit_output_registers""".split()
SPEC_O2T_NAMES = (
    "controlbox_do tool_do analog_output_type analog_output bit_input_registers".split()
)


def test_assembly_sizes_are_284_and_20() -> None:
    assert T2O_ASSEMBLY.size_bytes == 284
    assert O2T_ASSEMBLY.size_bytes == 20


@pytest.mark.parametrize("assembly", ASSEMBLIES, ids=lambda a: a.name)
def test_no_field_overlaps_another_or_runs_past_the_end(assembly: Assembly) -> None:
    owner: dict[int, str] = {}
    for f in assembly.fields:
        for bit in range(f.first_wire_bit, f.first_wire_bit + f.bit_count):
            assert bit < assembly.size_bytes * 8, f"{f.name} runs past the end"
            assert bit not in owner, f"{f.name} overlaps {owner.get(bit)} at bit {bit}"
            owner[bit] = f.name


@pytest.mark.parametrize(
    ("assembly", "names"),
    [(T2O_ASSEMBLY, SPEC_T2O_NAMES), (O2T_ASSEMBLY, SPEC_O2T_NAMES)],
    ids=["T2O", "O2T"],
)
def test_every_spec_name_is_present_once_in_order(assembly: Assembly, names: list[str]) -> None:
    assert [f.name for f in assembly.fields] == names


def test_channel_labels_match_counts() -> None:
    for assembly in ASSEMBLIES:
        for f in assembly.fields:
            assert not f.channels or len(f.channels) == f.count, f.name


def test_robot_state_enum_is_the_tables() -> None:
    assert [s.value for s in ROBOT_STATES] == list(range(21))
    assert [s.name for s in ROBOT_STATES] == STATE_NAMES
    assert [s.name for s in RobotState] == STATE_NAMES
    assert robot_state_name(14) == "STANDALONE_RUNNING"
    assert robot_state_name(21) == "UNKNOWN"
    assert all(s.description and s.pendant_colours for s in ROBOT_STATES)
    table_colours = {s.name: s.pendant_colours for s in ROBOT_STATES if s.colour_from_table}
    assert table_colours == {
        "STANDALONE_STANDBY": ("white",),
        "STANDALONE_RUNNING": ("white",),
        "COLLABORATIVE_STANDBY": ("green",),
        "COLLABORATIVE_RUNNING": ("green",),
        "HIGH_PRIORITY_RUNNING": ("white", "yellow"),
    }


def test_every_state_has_plain_words_distinct_from_its_enum_name() -> None:
    labels = [s.label for s in ROBOT_STATES]
    assert all(labels), "every state needs its plain-words label"
    assert len(set(labels)) == len(labels), "two states read the same"
    assert all(s.label != s.name for s in ROBOT_STATES)
    by_name = {s.name: s.label for s in ROBOT_STATES}
    assert by_name["STANDALONE_RUNNING"] == "Standalone running"
    assert by_name["INTERRUPTED"] == "Protective stop"


def test_five_flags_in_the_tables_order() -> None:
    flags = flag_fields()
    assert [f.flag.abbreviation for f in flags if f.flag] == ["SO", "SS", "ES", "DTBP", "PBP"]
    assert [f.first_bit for f in flags] == [16, 17, 18, 19, 20]


def test_generated_files_are_not_stale() -> None:
    stale = codegen.stale_outputs()
    assert not stale, f"run `cobot-hmi codegen`: stale {[str(p) for p in stale]}"


def test_packaged_layout_json_is_the_layout_document() -> None:
    text = resources.files("cobot_hmi").joinpath("generated/layout.json").read_text("utf-8")
    assert json.loads(text) == codegen.layout_document()
