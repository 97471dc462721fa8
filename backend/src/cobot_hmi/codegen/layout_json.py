"""Layer: layout tooling. The layout as one JSON document (served at ``/api/v1/layout``)."""

from __future__ import annotations

import json

from cobot_hmi.layout import (
    ANALOG_OUTPUT_RANGES,
    ASSEMBLIES,
    LAYOUT_VERSION,
    ROBOT_STATES,
    UNKNOWN_STATE_NAME,
    Field,
)


def _field_json(f: Field) -> dict[str, object]:
    data: dict[str, object] = {
        "name": f.name,
        "offset": f.offset,
        "cip_type": f.cip_type.value,
        "count": f.count,
        "first_bit": f.first_bit,
        "bit_count": f.bit_count,
        "scalar": f.scalar,
        "value_kind": f.value_kind,
        "unit": f.unit,
        "group": f.group,
        "description": f.description,
        "channels": list(f.channels),
    }
    if f.value_names:
        data["value_names"] = list(f.value_names)
    if f.element_names:
        data["element_names"] = list(f.element_names)
    if f.flag is not None:
        data["flag"] = {"abbreviation": f.flag.abbreviation, "full_name": f.flag.full_name}
    if f.enum:
        data["enum"] = f.enum
    return data


def layout_document() -> dict[str, object]:
    """The whole layout as one JSON-able document (served at ``/api/v1/layout``)."""
    return {
        "layout_version": LAYOUT_VERSION,
        "assemblies": [
            {
                "name": a.name,
                "direction": a.direction.value,
                "size_bytes": a.size_bytes,
                "default_instance": a.default_instance,
                "description": a.description,
                "fields": [_field_json(f) for f in a.fields],
            }
            for a in ASSEMBLIES
        ],
        "robot_states": [
            {
                "value": s.value,
                "name": s.name,
                "label": s.label,
                "description": s.description,
                "pendant_colours": list(s.pendant_colours),
                "colour_from_table": s.colour_from_table,
            }
            for s in ROBOT_STATES
        ],
        "unknown_state_name": UNKNOWN_STATE_NAME,
        "analog_output_ranges": {
            coding: {"low": low, "high": high, "unit": unit}
            for coding, (low, high, unit) in ANALOG_OUTPUT_RANGES.items()
        },
    }


def layout_json() -> str:
    return json.dumps(layout_document(), indent=2, ensure_ascii=False) + "\n"
