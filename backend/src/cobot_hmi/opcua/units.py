"""Layer: service (OPC UA). The layout's units as OPC UA engineering units (UNECE codes).

OPC UA names a unit by its UN/CEFACT common code (Part 8 §5.6.3: ``EUInformation`` with the
code packed into ``UnitId``). Every unit the layout writes (``cobot_hmi.layout``) maps to one
here; ``unit_for`` refuses one it does not know, so a new unit in the layout stops the server
at its start (and the test of this module) instead of going out without its unit. The analog
channels' "mA or V per its type" follow their type field: milliampere or volt per channel.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

from asyncua import ua

from cobot_hmi.layout import ANALOG_OUTPUT_RANGES

UNECE_URI: Final = "http://www.opcfoundation.org/UA/units/un/cefact"
PER_TYPE: Final = "mA or V per its type"
"""The layout's unit of an analog value whose unit is its channel's type (current, voltage)."""


@dataclass(frozen=True, slots=True)
class Unit:
    code: str
    """UN/CEFACT common code."""
    symbol: str
    name: str

    @property
    def unit_id(self) -> int:
        """The code's characters packed into an Int32, last character lowest (Part 8)."""
        unit_id = 0
        for position, char in enumerate(reversed(self.code)):
            unit_id |= ord(char) << (8 * position)
        return unit_id

    def information(self) -> ua.EUInformation:
        return ua.EUInformation(
            NamespaceUri=UNECE_URI,
            UnitId=self.unit_id,
            DisplayName=ua.LocalizedText(self.symbol),
            Description=ua.LocalizedText(self.name),
        )


UNITS: Final = {
    "degree": Unit("DD", "°", "degree [unit of angle]"),
    "degree/s": Unit("E96", "°/s", "degree per second"),
    "A": Unit("AMP", "A", "ampere"),
    "°C": Unit("CEL", "°C", "degree Celsius"),
    "N·m": Unit("NU", "N·m", "newton metre"),
    "mm": Unit("MMT", "mm", "millimetre"),
    "mm/s": Unit("C16", "mm/s", "millimetre per second"),
    "N": Unit("NEW", "N", "newton"),
    "mA": Unit("4K", "mA", "milliampere"),
    "V": Unit("VLT", "V", "volt"),
    "%": Unit("P1", "%", "percent"),
}
"""Keyed by the layout's unit strings (``Field.unit``) and ``ANALOG_OUTPUT_RANGES``' units."""


class UnknownUnitError(KeyError):
    """A unit of the layout with no UN/CEFACT code here."""


def unit_for(layout_unit: str) -> Unit:
    try:
        return UNITS[layout_unit]
    except KeyError:
        raise UnknownUnitError(
            f"the layout's unit {layout_unit!r} has no UN/CEFACT code in cobot_hmi.opcua.units"
        ) from None


def analog_unit(type_name: str) -> tuple[Unit, ua.Range]:
    """An analog channel's unit and range for its type (``current`` or ``voltage``: the
    layout's ``value_names`` of the type field)."""
    low, high, symbol = ANALOG_OUTPUT_RANGES[type_name]
    return unit_for(symbol), ua.Range(Low=low, High=high)
