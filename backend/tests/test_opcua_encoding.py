"""The fast paths of asyncua's encoder (``opcua.encoding``) write asyncua's own bytes: for any
DataValue and MonitoredItemNotification Hypothesis makes (every Variant type the server writes
and others, scalars and arrays, values that do not fit their type, statuses, timestamps with and
without a zone, picoseconds), the bytes equal asyncua's structure encoder's, asyncua's decoder
reads them back, and what cannot be encoded fails as asyncua fails."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta, timezone
from typing import Any

import pytest
from asyncua import ua
from asyncua.common.utils import Buffer
from asyncua.ua import ua_binary
from asyncua.ua.uaerrors import UaError
from hypothesis import given, settings
from hypothesis import strategies as st

from cobot_hmi.opcua import encoding
from cobot_hmi.opcua.values import scalar_variant, shared_value

encoding.install()

INTEGERS = {
    ua.VariantType.SByte: (-(2**7), 2**7 - 1),
    ua.VariantType.Byte: (0, 2**8 - 1),
    ua.VariantType.Int16: (-(2**15), 2**15 - 1),
    ua.VariantType.UInt16: (0, 2**16 - 1),
    ua.VariantType.Int32: (-(2**31), 2**31 - 1),
    ua.VariantType.UInt32: (0, 2**32 - 1),
    ua.VariantType.Int64: (-(2**63), 2**63 - 1),
    ua.VariantType.UInt64: (0, 2**64 - 1),
}


def integer_variants() -> st.SearchStrategy[ua.Variant]:
    return st.sampled_from(sorted(INTEGERS, key=lambda t: t.value)).flatmap(
        lambda t: st.integers(*INTEGERS[t]).map(lambda v: scalar_variant(v, t))
    )


float_variants = st.one_of(
    st.floats(width=32).map(lambda v: scalar_variant(v, ua.VariantType.Float)),
    st.floats().map(lambda v: scalar_variant(v, ua.VariantType.Double)),
)
other_variants = st.one_of(
    st.booleans().map(lambda v: scalar_variant(v, ua.VariantType.Boolean)),
    st.text(max_size=20).map(lambda v: ua.Variant(v, ua.VariantType.String)),
    st.lists(st.floats(width=32), max_size=6).map(lambda v: ua.Variant(v, ua.VariantType.Float)),
    st.lists(st.booleans(), max_size=6).map(lambda v: ua.Variant(v, ua.VariantType.Boolean)),
    st.just(ua.Variant(None, ua.VariantType.Null)),
    st.text(max_size=10).map(
        lambda v: ua.Variant(ua.LocalizedText(v), ua.VariantType.LocalizedText)
    ),
)
variants = st.one_of(integer_variants(), float_variants, other_variants)
statuses = st.one_of(
    st.none(),
    st.sampled_from(
        [
            ua.StatusCodes.Good,
            ua.StatusCodes.BadWaitingForInitialData,
            ua.StatusCodes.BadNotSupported,
        ]
    ).map(ua.StatusCode),
)
zones = st.sampled_from([UTC, timezone(timedelta(hours=1)), None])
times = st.one_of(
    st.none(),
    st.builds(
        lambda s, zone: datetime(2020, 1, 1, tzinfo=zone) + timedelta(seconds=s),
        st.floats(0, 3e8),
        zones,
    ),
)
picoseconds = st.one_of(st.none(), st.integers(0, 9999))


@st.composite
def data_values(draw: Any) -> ua.DataValue:
    value = shared_value(draw(variants), draw(statuses), draw(times), draw(times))
    value.Value = draw(st.one_of(st.just(value.Value), st.none()))
    value.SourcePicoseconds = draw(picoseconds)
    value.ServerPicoseconds = draw(picoseconds)
    return value


@settings(max_examples=400, deadline=None)
@given(data_values())
def test_a_data_value_is_asyncuas_bytes_and_reads_back(value: ua.DataValue) -> None:
    fast = encoding.encode_data_value(value)
    assert fast == encoding.asyncua_encoding(ua.DataValue, value)
    assert ua_binary.to_binary(ua.DataValue, value) == fast  # asyncua's entry point: the fast path
    back = ua_binary.struct_from_binary(ua.DataValue, Buffer(fast))  # asyncua reads it
    if value.Value is not None and value.Value.VariantType is not ua.VariantType.Null:
        assert back.Value.VariantType == value.Value.VariantType
        if not value.Value.is_array and isinstance(value.Value.Value, int):
            assert back.Value.Value == value.Value.Value
    if value.StatusCode is not None:
        assert back.StatusCode == value.StatusCode


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 2**32 - 1), data_values())
def test_a_notification_is_asyncuas_bytes(handle: int, value: ua.DataValue) -> None:
    notification = ua.MonitoredItemNotification(ClientHandle=handle, Value=value)
    fast = encoding.encode_monitored_item_notification(notification)
    assert fast == encoding.asyncua_encoding(ua.MonitoredItemNotification, notification)
    changes = ua.DataChangeNotification(MonitoredItems=[notification, notification])
    whole = ua_binary.extensionobject_to_binary(changes)  # asyncua's list, with the fast path
    assert (b"\x02\x00\x00\x00" + fast + fast) in whole  # the count, then both


def test_the_fast_path_is_the_one_asyncua_uses() -> None:
    """Installed: asyncua's encoder hands these structures to the fast functions (a change of
    asyncua's that bypassed them would make this fail, not the figures quietly worse)."""
    assert ua_binary.create_dataclass_serializer(ua.DataValue) is encoding.encode_data_value
    assert (
        ua_binary.create_dataclass_serializer(ua.MonitoredItemNotification)
        is encoding.encode_monitored_item_notification
    )
    assert ua_binary.create_dataclass_serializer(
        ua.ReadValueId
    ) is encoding.ASYNCUA_DATACLASS_SERIALIZER(ua.ReadValueId)


@pytest.mark.parametrize(
    "variant",
    [
        scalar_variant(2**40, ua.VariantType.Int32),
        scalar_variant(-1, ua.VariantType.UInt16),
        scalar_variant("x", ua.VariantType.Double),
    ],
)
def test_a_value_that_does_not_fit_fails_as_asyncua_fails(variant: ua.Variant) -> None:
    value = shared_value(variant, ua.StatusCode(ua.StatusCodes.Good), None, None)  # type: ignore[arg-type]
    with pytest.raises(UaError) as asyncua_error:
        encoding.asyncua_encoding(ua.DataValue, value)
    with pytest.raises(UaError) as fast_error:
        encoding.encode_data_value(value)
    assert str(fast_error.value) == str(asyncua_error.value)
