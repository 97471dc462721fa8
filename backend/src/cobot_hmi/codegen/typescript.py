"""Layer: layout tooling. Writes ``frontend/src/generated/layout.ts``: types and constants."""

from __future__ import annotations

import json
from typing import Final

from cobot_hmi.codegen.common import HEADER, quoted
from cobot_hmi.codegen.layout_json import layout_document
from cobot_hmi.layout import (
    LAYOUT_VERSION,
    O2T_ASSEMBLY,
    ROBOT_STATES,
    T2O_ASSEMBLY,
    UNKNOWN_STATE_NAME,
    Field,
)


def _ts_type(f: Field, for_patch: bool = False) -> str:
    if f.element_names:
        return "{ " + "; ".join(f"readonly {n}: number" for n in f.element_names) + " }"
    element = {"bool": "boolean", "int": "number", "float": "number | null"}[f.value_kind]
    if for_patch:
        element = element.replace(" | null", "")
        return f"Readonly<Record<string, {element}>>"
    if f.scalar:
        return element
    return f"readonly ({element})[]" if "|" in element else f"readonly {element}[]"


def layout_ts() -> str:
    out = _frame_types()
    out += [
        "export type FrameFieldName = "
        + " | ".join(quoted(f.name) for f in T2O_ASSEMBLY.fields)
        + ";",
        "export type CommandFieldName = "
        + " | ".join(quoted(f.name) for f in O2T_ASSEMBLY.fields)
        + ";",
        "",
        *_LAYOUT_INTERFACES,
        "export const LAYOUT: Layout = "
        + json.dumps(layout_document(), indent=2, ensure_ascii=False)
        + ";",
        "",
    ]
    return "\n".join(out)


def _frame_types() -> list[str]:
    """The version, the state names and the frame, command image and patch interfaces."""
    state_names = " | ".join(f'"{s.name}"' for s in ROBOT_STATES)
    out = [
        f"// {HEADER}",
        "// Run `cobot-hmi codegen` after changing the layout.",
        "",
        f"export const LAYOUT_VERSION = {LAYOUT_VERSION};",
        f'export const UNKNOWN_STATE_NAME = "{UNKNOWN_STATE_NAME}";',
        "",
        f"export type RobotStateName = {state_names};",
        "",
        "/** A decoded T→O frame as the backend sends it (non-finite REALs arrive as null). */",
        "export interface Frame {",
    ]
    for f in T2O_ASSEMBLY.fields:
        unit = f" [{f.unit}]" if f.unit else ""
        out.append(f"  /** {f.description}{unit} */")
        out.append(f"  readonly {f.name}: {_ts_type(f)};")
        if f.enum:
            out.append(f"  readonly {f.name}_name: RobotStateName | typeof UNKNOWN_STATE_NAME;")
    out += ["}", "", "/** The O→T command image. */", "export interface CommandImage {"]
    for f in O2T_ASSEMBLY.fields:
        out.append(f"  /** {f.description} */")
        out.append(f"  readonly {f.name}: {_ts_type(f)};")
    out += [
        "}",
        "",
        "/** A partial command image: each array as a map from index (a string) to value. */",
        "export interface CommandPatch {",
    ]
    out += [f"  readonly {f.name}?: {_ts_type(f, for_patch=True)};" for f in O2T_ASSEMBLY.fields]
    out += ["}", ""]
    return out


_LAYOUT_INTERFACES: Final = [
    "export interface FieldInfo {",
    "  readonly name: string;",
    "  readonly offset: number;",
    "  readonly cip_type: string;",
    "  readonly count: number;",
    "  readonly first_bit: number | null;",
    "  readonly bit_count: number;",
    "  readonly scalar: boolean;",
    '  readonly value_kind: "bool" | "int" | "float";',
    "  readonly unit: string;",
    "  readonly group: string;",
    "  readonly description: string;",
    "  readonly channels: readonly string[];",
    "  readonly value_names?: readonly string[];",
    "  readonly element_names?: readonly string[];",
    "  readonly flag?: { readonly abbreviation: string; readonly full_name: string };",
    "  readonly enum?: string;",
    "}",
    "",
    "export interface RobotStateInfo {",
    "  readonly value: number;",
    "  readonly name: RobotStateName;",
    '  /** The state in plain words ("Standalone running"); `name` stays the identifier. */',
    "  readonly label: string;",
    "  readonly description: string;",
    "  readonly pendant_colours: readonly string[];",
    "  readonly colour_from_table: boolean;",
    "}",
    "",
    "export interface AssemblyInfo {",
    "  readonly name: string;",
    '  readonly direction: "T2O" | "O2T";',
    "  readonly size_bytes: number;",
    "  readonly default_instance: number;",
    "  readonly description: string;",
    "  readonly fields: readonly FieldInfo[];",
    "}",
    "",
    "export interface AnalogRange {",
    "  readonly low: number;",
    "  readonly high: number;",
    "  readonly unit: string;",
    "}",
    "",
    "export interface Layout {",
    "  readonly layout_version: number;",
    "  readonly assemblies: readonly AssemblyInfo[];",
    "  readonly robot_states: readonly RobotStateInfo[];",
    "  readonly unknown_state_name: string;",
    "  readonly analog_output_ranges: Readonly<Record<string, AnalogRange>>;",
    "}",
    "",
]
"""What the layout's JSON document holds, as TypeScript interfaces (fixed text)."""
