"""Layer: service (Sparkplug). Pure: Sparkplug B payloads to and from protobuf bytes.

The message classes are generated from ``sparkplug_b.proto`` (``cobot_hmi.generated.
sparkplug_b_pb2``, written by ``cobot-hmi codegen``). Data type numbers and how each sits in
the metric's ``value`` oneof are the specification's (Sparkplug 3.0, "Payloads": integers up
to 32 bits in ``int_value``, 64-bit ones in ``long_value``, ``Float`` in ``float_value``).

Imports only the generated classes: the only protobuf import.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from enum import IntEnum
from typing import TYPE_CHECKING, TypeAlias

from cobot_hmi.generated.sparkplug_b_pb2 import Payload

if TYPE_CHECKING:
    from google.protobuf.internal.containers import RepeatedCompositeFieldContainer

__all__ = [
    "DataMetricWriter",
    "DataType",
    "MetricValue",
    "Payload",
    "PayloadError",
    "add_metric",
    "data_metric_writer",
    "make_payload",
    "metric_value",
    "parse_payload",
]


class DataType(IntEnum):
    """Sparkplug B data types (the numbers the specification gives them)."""

    INT8 = 1
    INT16 = 2
    INT32 = 3
    INT64 = 4
    UINT8 = 5
    UINT16 = 6
    UINT32 = 7
    UINT64 = 8
    FLOAT = 9
    DOUBLE = 10
    BOOLEAN = 11
    STRING = 12
    DATETIME = 13
    TEXT = 14


class PayloadError(ValueError):
    """Bytes that are not a Sparkplug B payload."""


MetricValue = bool | int | float | str

_INT32_TYPES = frozenset({DataType.INT8, DataType.INT16, DataType.INT32})
_UINT32_TYPES = frozenset({DataType.UINT8, DataType.UINT16, DataType.UINT32})
_LONG_TYPES = frozenset({DataType.INT64, DataType.UINT64, DataType.DATETIME})


@dataclass(frozen=True, slots=True)
class Property:
    key: str
    datatype: DataType
    value: MetricValue


def _set_value(target: Payload.Metric, datatype: DataType, value: MetricValue) -> None:
    if datatype is DataType.BOOLEAN:
        target.boolean_value = bool(value)
    elif datatype is DataType.FLOAT:
        target.float_value = float(value)
    elif datatype is DataType.DOUBLE:
        target.double_value = float(value)
    elif datatype in _UINT32_TYPES:
        target.int_value = int(value)
    elif datatype in _INT32_TYPES:
        target.int_value = int(value) & 0xFFFFFFFF  # two's complement in a uint32 (the spec)
    elif datatype in _LONG_TYPES:
        target.long_value = int(value) & 0xFFFFFFFFFFFFFFFF
    else:
        target.string_value = str(value)


def add_metric(
    payload: Payload,
    *,
    alias: int | None,
    timestamp_ms: int,
    datatype: DataType,
    value: MetricValue | None,
    name: str | None = None,
    properties: Sequence[Property] = (),
    with_datatype: bool = True,
) -> Payload.Metric:
    """Append one metric: name on births (and by-name metrics), alias from then on; a value of
    ``None`` is Null (``is_null``, Sparkplug 3.0: the value is not known)."""
    metric = payload.metrics.add()
    if name is not None:
        metric.name = name
    if alias is not None:
        metric.alias = alias
    metric.timestamp = timestamp_ms
    if with_datatype:
        metric.datatype = datatype
    if value is None:
        metric.is_null = True
    else:
        _set_value(metric, datatype, value)
    if properties:
        props = metric.properties
        for prop in properties:
            props.keys.append(prop.key)
            entry = props.values.add()
            entry.type = prop.datatype
            if prop.datatype is DataType.STRING:
                entry.string_value = str(prop.value)
            elif prop.datatype is DataType.BOOLEAN:
                entry.boolean_value = bool(prop.value)
            elif prop.datatype in _LONG_TYPES:
                entry.long_value = int(prop.value)
            elif prop.datatype in (DataType.FLOAT,):
                entry.float_value = float(prop.value)
            else:
                entry.int_value = int(prop.value)
    return metric


Metrics: TypeAlias = "RepeatedCompositeFieldContainer[Payload.Metric]"
DataMetricWriter: TypeAlias = Callable[["Metrics", int, int, MetricValue], object]
"""Appends to a payload's ``metrics`` one metric of a DATA message: ``(metrics, alias,
timestamp_ms, value)``."""


# One ``add`` with keywords per metric: a DDATA carries tens of them and setting each field on
# its own costs a call into protobuf per field (issue 40). The same fields as ``add_metric``
# with ``with_datatype=False`` and no name or properties, so the same bytes (a test compares).
def _add_boolean(metrics: Metrics, alias: int, timestamp_ms: int, value: MetricValue) -> object:
    return metrics.add(alias=alias, timestamp=timestamp_ms, boolean_value=bool(value))


def _add_float(metrics: Metrics, alias: int, timestamp_ms: int, value: MetricValue) -> object:
    return metrics.add(alias=alias, timestamp=timestamp_ms, float_value=float(value))


def _add_double(metrics: Metrics, alias: int, timestamp_ms: int, value: MetricValue) -> object:
    return metrics.add(alias=alias, timestamp=timestamp_ms, double_value=float(value))


def _add_uint32(metrics: Metrics, alias: int, timestamp_ms: int, value: MetricValue) -> object:
    return metrics.add(alias=alias, timestamp=timestamp_ms, int_value=int(value))


def _add_int32(metrics: Metrics, alias: int, timestamp_ms: int, value: MetricValue) -> object:
    return metrics.add(alias=alias, timestamp=timestamp_ms, int_value=int(value) & 0xFFFFFFFF)


def _add_long(metrics: Metrics, alias: int, timestamp_ms: int, value: MetricValue) -> object:
    return metrics.add(
        alias=alias, timestamp=timestamp_ms, long_value=int(value) & 0xFFFFFFFFFFFFFFFF
    )


def _add_string(metrics: Metrics, alias: int, timestamp_ms: int, value: MetricValue) -> object:
    return metrics.add(alias=alias, timestamp=timestamp_ms, string_value=str(value))


def data_metric_writer(datatype: DataType) -> DataMetricWriter:
    """How a DATA message carries a metric of ``datatype`` by alias (no datatype: the birth
    gave it, Sparkplug 3.0): what ``add_metric(..., with_datatype=False)`` appends for a
    value that is not ``None``, without a name or properties, in one call."""
    if datatype is DataType.BOOLEAN:
        return _add_boolean
    if datatype is DataType.FLOAT:
        return _add_float
    if datatype is DataType.DOUBLE:
        return _add_double
    if datatype in _UINT32_TYPES:
        return _add_uint32
    if datatype in _INT32_TYPES:
        return _add_int32
    if datatype in _LONG_TYPES:
        return _add_long
    return _add_string


def make_payload(timestamp_ms: int, seq: int | None) -> Payload:
    payload = Payload()
    payload.timestamp = timestamp_ms
    if seq is not None:
        payload.seq = seq
    return payload


def parse_payload(data: bytes) -> Payload:
    """Decode bytes; ``PayloadError`` when they are not a payload."""
    payload = Payload()
    try:
        payload.ParseFromString(data)
    except Exception as error:  # protobuf raises DecodeError and, for some bytes, others
        raise PayloadError(f"not a Sparkplug B payload: {error}") from None
    return payload


def metric_value(metric: Payload.Metric) -> MetricValue | None:
    """The value a metric carries, typed by which ``value`` field is set (``None``: none)."""
    which = metric.WhichOneof("value")
    if which is None or metric.is_null:
        return None
    if which == "boolean_value":
        return metric.boolean_value
    if which == "float_value":
        return metric.float_value
    if which == "double_value":
        return metric.double_value
    if which == "int_value":
        return metric.int_value
    if which == "long_value":
        return metric.long_value
    if which == "string_value":
        return metric.string_value
    return None
