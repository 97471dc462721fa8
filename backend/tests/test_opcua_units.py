"""The OPC UA server's pure parts: its settings, the layout's units as UN/CEFACT codes, the
safety state's reading of the frame, the bundled NodeSets' provenance, the values shared with
asyncua's monitored items, the ticks' grid that subscriptions start in phase with, and which
robots a tick updates (as often as their fastest watcher samples)."""

from __future__ import annotations

import copy
import xml.etree.ElementTree as ET
from datetime import UTC, datetime, timedelta, timezone

import pytest
from asyncua import ua
from asyncua.server.address_space import AddressSpace, AttributeValue, NodeData
from asyncua.server.internal_subscription import InternalSubscription
from asyncua.server.monitored_item_service import MonitoredItemData
from asyncua.ua.ua_binary import struct_to_binary

from cobot_hmi.codec import zero_frame
from cobot_hmi.generated.frames import RobotState
from cobot_hmi.layout import ANALOG_OUTPUT_RANGES, O2T_FIELDS, T2O_FIELDS
from cobot_hmi.opcua import companion, robotics, sessions
from cobot_hmi.opcua import values as opcua_values
from cobot_hmi.opcua.opcua_settings import DEFAULT_PORT
from cobot_hmi.opcua.server import (
    PUBLISH_AFTER_TICK,
    SamplingPlan,
    subscription_delay_s,
    tick_deadline,
    watched_intervals,
)
from cobot_hmi.opcua.units import PER_TYPE, analog_unit, unit_for
from cobot_hmi.opcua.values import (
    GOOD,
    SharedDataValue,
    run_later,
    scalar_variant,
    shared_value,
    tell_monitored_items,
    win_epoch,
)
from cobot_hmi.service.config.loading import load_settings
from cobot_hmi.service.service_settings import SettingsError
from cobot_hmi.settings import HmiSettings

UA_NS = "{http://opcfoundation.org/UA/2011/03/UANodeSet.xsd}"


@pytest.mark.parametrize(
    ("url", "bind", "loopback"),
    [
        ("opc.tcp://127.0.0.1", ("127.0.0.1", DEFAULT_PORT), True),
        ("opc.tcp://localhost:4841/", ("localhost", 4841), True),
        ("opc.tcp://[::1]:4842", ("::1", 4842), True),
        ("opc.tcp://0.0.0.0:4840", ("0.0.0.0", 4840), False),
        ("opc.tcp://cell.example.org", ("cell.example.org", DEFAULT_PORT), False),
    ],
)
def test_the_url_names_the_bind(url: str, bind: tuple[str, int], loopback: bool) -> None:
    settings = HmiSettings.from_keys(robot_host="127.0.0.2", opcua_url=url)
    assert settings.opcua.opcua_enabled
    assert settings.opcua.opcua_bind == bind
    assert settings.opcua.opcua_loopback is loopback


def test_off_by_default_and_a_bad_url_is_refused_naming_it() -> None:
    settings = HmiSettings.from_keys(robot_host="127.0.0.2")
    assert not settings.opcua.opcua_enabled and not settings.opcua.opcua_writes
    assert settings.opcua.opcua_monitoring_hz == 10.0
    with pytest.raises(SettingsError, match="opcua_url"):
        load_settings(
            {"robot_host": "127.0.0.2", "opcua_url": "http://example.org"}, None, None, HmiSettings
        )


def test_every_unit_of_the_layout_has_a_unece_code() -> None:
    for field in (*T2O_FIELDS, *O2T_FIELDS):
        if field.unit and field.unit != PER_TYPE:
            assert unit_for(field.unit).code
    for kind, (low, high, symbol) in ANALOG_OUTPUT_RANGES.items():
        unit, span = analog_unit(kind)
        assert unit.symbol == symbol and (span.Low, span.High) == (low, high)
    # Part 8's packing: the code's characters, the last one lowest.
    assert unit_for("°C").unit_id == 4408652  # "CEL"
    assert unit_for("degree").unit_id == 0x4444  # "DD"


def test_the_safety_state_reads_the_frame() -> None:
    frame = zero_frame()._replace(robot_state=int(RobotState.STANDALONE_RUNNING))
    assert not robotics.emergency_stop(frame) and not robotics.protective_stop(frame)
    assert robotics.operational_mode(frame) == companion.MODE_AUTOMATIC
    assert robotics.emergency_stop(frame._replace(emergency_stopped=True))
    assert robotics.emergency_stop(frame._replace(robot_state=int(RobotState.EMERGENCY_STOP)))
    assert robotics.protective_stop(frame._replace(robot_state=int(RobotState.INTERRUPTED)))
    manual = frame._replace(robot_state=int(RobotState.MANUAL_JOGGING))
    assert robotics.operational_mode(manual) == companion.MODE_MANUAL_REDUCED_SPEED
    other = frame._replace(robot_state=int(RobotState.SAFE_OFF))
    assert robotics.operational_mode(other) == companion.MODE_OTHER


def test_the_bundled_nodesets_are_the_models_named() -> None:
    """Each bundled file declares the model it is loaded as, carries the OPC Foundation's
    licence, and holds every node ``companion`` names under its browse name."""
    for file_name, uri in companion.NODESETS:
        path = companion.NODESET_DIR / file_name
        text = path.read_text(encoding="utf-8")
        assert "OPC Foundation MIT License 1.00" in text
        root = ET.parse(path).getroot()
        models = [m.get("ModelUri") for m in root.iter(f"{UA_NS}Model")]
        assert models == [uri]
        uris = [u.text for u in root.find(f"{UA_NS}NamespaceUris") or []]
        index = uris.index(uri) + 1
        names = {el.get("NodeId"): el.get("BrowseName") for el in root if el.get("NodeId")}
        for ref in companion.ALL_REFS:
            if ref.uri == uri:
                assert names[f"ns={index};i={ref.identifier}"] == f"{index}:{ref.name}", ref


def test_a_shared_data_value_is_its_own_copy_and_encodes_as_a_data_value() -> None:
    when = datetime(2026, 11, 27, 15, 0, tzinfo=UTC)
    fields = {"SourceTimestamp": when, "ServerTimestamp": when}
    variant = ua.Variant(1.5, ua.VariantType.Float)
    shared = SharedDataValue(variant, StatusCode=GOOD, **fields)
    assert copy.deepcopy(shared) is shared  # asyncua's monitored items copy every change
    plain = ua.DataValue(ua.Variant(1.5, ua.VariantType.Float), StatusCode=GOOD, **fields)
    notification = ua.MonitoredItemNotification(ClientHandle=7, Value=shared)
    expected = ua.MonitoredItemNotification(ClientHandle=7, Value=plain)
    assert struct_to_binary(notification) == struct_to_binary(expected)


def test_a_late_tick_keeps_the_grid() -> None:
    assert tick_deadline(10.0, 10.05, 0.1) == 10.0  # late by less than a period: runs as is
    assert tick_deadline(10.0, 10.35, 0.1) == pytest.approx(10.3)  # three missed, skipped
    # the ticks after it stay on 10.0 + k · 0.1, where the subscriptions' cycles started


@pytest.mark.parametrize("now", [9.9, 9.95, 10.0, 10.019, 10.07, 12.345])
def test_a_subscription_starts_just_after_a_tick(now: float) -> None:
    period_s, next_tick = 0.1, 10.1  # ticks at 10.0, 10.1, …
    delay = subscription_delay_s(now, next_tick, period_s)
    assert 0 <= delay < period_s
    phase = (now + delay - next_tick) % period_s  # where in the period the cycle starts
    assert phase == pytest.approx(PUBLISH_AFTER_TICK * period_s, abs=1e-9)


def _subscription(publishing_ms: float, *nodes: ua.NodeId) -> InternalSubscription:
    """asyncua's own subscription, its monitored items on ``nodes`` (as it holds them)."""
    data = ua.CreateSubscriptionResult(RevisedPublishingInterval=publishing_ms)
    subscription = InternalSubscription(data, AddressSpace(), _publish, ua.NodeId(1, 0))
    service = subscription.monitored_item_srv
    for node in nodes:
        service._monitored_item_counter += 1
        item = MonitoredItemData()
        item.read_value_id = ua.ReadValueId(NodeId=node, AttributeId=ua.AttributeIds.Value)
        service._monitored_items[service._monitored_item_counter] = item
    return subscription


async def _publish(*_: object) -> None:  # pragma: no cover - never published here
    return None


def test_each_robot_is_updated_as_often_as_its_fastest_watcher_samples() -> None:
    robots = {2: "a", 3: "b", 4: "c"}  # by namespace index; nobody watches c
    historian = _subscription(1000.0, ua.NodeId("x", 2), ua.NodeId("y", 3), ua.NodeId(85, 0))
    screen = _subscription(100.0, ua.NodeId("z", 3))
    assert watched_intervals({1: historian, 2: screen}, robots, 0.1) == {"a": 1.0, "b": 0.1}
    plan = SamplingPlan(robots, 0.1)
    plan.refresh({1: historian, 2: screen})
    assert [sum(plan.due(name, tick) for tick in range(100)) for name in "abc"] == [10, 100, 0]
    assert [tick for tick in range(20) if plan.due("a", tick)] == [0, 10]
    plan.refresh({1: historian})  # the screen's subscription deleted: b as the historian
    assert plan.every == {"a": 10, "b": 10}
    assert [tick for tick in range(20) if plan.due("b", tick)] == [9, 19]  # spread over ticks
    faster = _subscription(50.0, ua.NodeId("x", 2))  # faster than the ticks: every tick
    plan.refresh({1: historian, 3: faster})
    assert plan.every["a"] == 1


@pytest.mark.parametrize(
    ("value", "variant"),
    [
        (1.5, ua.VariantType.Double),
        (7, ua.VariantType.UInt16),
        (True, ua.VariantType.Boolean),
        ("text", ua.VariantType.String),
        (None, ua.VariantType.String),
        ([1.0, 2.0], ua.VariantType.Float),
    ],
)
def test_values_made_without_the_checks_equal_the_constructors(
    value: object, variant: ua.VariantType
) -> None:
    made = scalar_variant(value, variant)
    assert made == ua.Variant(value, variant)
    assert (made.Dimensions, made.is_array) == (None, isinstance(value, list))
    when = datetime(2026, 12, 7, tzinfo=UTC)
    fast = shared_value(made, GOOD, when, when)
    slow = SharedDataValue(made, StatusCode=GOOD, SourceTimestamp=when, ServerTimestamp=when)
    assert fast == slow
    assert struct_to_binary(fast) == struct_to_binary(slow)


async def test_deleting_every_item_of_a_subscription_removes_each_callback_once() -> None:
    aspace = AddressSpace()
    nodes = [ua.NodeId(f"v{i}", 2) for i in range(300)]
    for node in nodes:
        data = NodeData(node)
        data.attributes[ua.AttributeIds.Value] = AttributeValue(ua.DataValue(ua.Variant(0.0)))
        aspace[node] = data
    result = ua.CreateSubscriptionResult(RevisedPublishingInterval=1000.0)
    subscription = InternalSubscription(result, aspace, _publish, ua.NodeId(1, 0))
    service = subscription.monitored_item_srv
    requests = [
        ua.MonitoredItemCreateRequest(
            ItemToMonitor=ua.ReadValueId(NodeId=node, AttributeId=ua.AttributeIds.Value),
            MonitoringMode=ua.MonitoringMode.Reporting,
            RequestedParameters=ua.MonitoringParameters(ClientHandle=i, QueueSize=1),
        )
        for i, node in enumerate(nodes)
    ]
    params = ua.CreateMonitoredItemsParameters(ItemsToCreate=requests)
    created = await service.create_monitored_items(params)
    assert all(r.StatusCode.is_good() for r in created)
    callbacks = [aspace[n].attributes[ua.AttributeIds.Value].datachange_callbacks for n in nodes]
    assert all(len(c) == 1 for c in callbacks)
    # sessions.py's, installed when it is imported: one pass, not one scan per item
    assert type(service).delete_all_monitored_items is sessions._delete_all_monitored_items
    service.delete_all_monitored_items()
    assert not any(callbacks)
    assert not service._monitored_items and not service._monitored_datachange


async def _watched(
    nodes: list[ua.NodeId],
    queue_sizes: list[int] | None = None,
    filters: list[ua.DataChangeFilter | None] | None = None,
    publishing_ms: float = 1000.0,
    published: list[ua.PublishResult] | None = None,
) -> tuple[AddressSpace, InternalSubscription]:
    """An address space holding ``nodes`` and a subscription with an item on each (queue 5
    unless ``queue_sizes`` says, no filter unless ``filters`` says); what it publishes is
    appended to ``published``."""
    aspace = AddressSpace()
    for node in nodes:
        data = NodeData(node)
        data.attributes[ua.AttributeIds.Value] = AttributeValue(ua.DataValue(ua.Variant(0.0)))
        aspace[node] = data

    async def publish(result: ua.PublishResult) -> None:
        if published is not None:
            published.append(result)

    result = ua.CreateSubscriptionResult(RevisedPublishingInterval=publishing_ms)
    subscription = InternalSubscription(result, aspace, publish, ua.NodeId(1, 0))
    sizes = queue_sizes or [5] * len(nodes)
    kinds = filters or [None] * len(nodes)
    requests = [
        ua.MonitoredItemCreateRequest(
            ItemToMonitor=ua.ReadValueId(NodeId=node, AttributeId=ua.AttributeIds.Value),
            MonitoringMode=ua.MonitoringMode.Reporting,
            RequestedParameters=ua.MonitoringParameters(
                ClientHandle=i,
                QueueSize=sizes[i],
                Filter=ua.ExtensionObject() if kinds[i] is None else kinds[i],
            ),
        )
        for i, node in enumerate(nodes)
    ]
    params = ua.CreateMonitoredItemsParameters(ItemsToCreate=requests)
    await subscription.monitored_item_srv.create_monitored_items(params)
    return aspace, subscription


async def test_the_values_notify_as_asyncua_would() -> None:
    """``values.tell_monitored_items`` against asyncua's own callback: the same notifications
    queued for the same writes (a repeated value none, a new status one, a disabled item none)."""
    nodes = [ua.NodeId("a", 2), ua.NodeId("b", 2)]
    when = datetime(2026, 12, 7, tzinfo=UTC)
    bad = ua.StatusCode(ua.StatusCodes.BadCommunicationError)
    writes = [(0, 1.0, GOOD), (0, 1.0, GOOD), (1, 2.0, GOOD), (0, None, bad), (0, 3.0, GOOD)]
    queued = []
    for fast in (False, True):
        aspace, subscription = await _watched(nodes)
        service = subscription.monitored_item_srv
        await service.set_monitoring_mode(
            ua.MonitoringMode.Disabled, [max(service._monitored_items)]
        )
        for index, number, status in writes:
            double = ua.VariantType.Double
            variant = ua.Variant() if number is None else scalar_variant(number, double)
            value = shared_value(variant, status, when, when)
            callbacks = aspace[nodes[index]].attributes[ua.AttributeIds.Value].datachange_callbacks
            if fast:
                await run_later(tell_monitored_items(callbacks, value) or [])
            else:
                for handle, callback in callbacks.items():
                    await callback(handle, value)
        queued.append(
            [
                struct_to_binary(n)
                for items in subscription._triggered_datachanges.values()
                for n in items
            ]
        )
    assert queued[0] == queued[1]
    assert len(queued[0]) == 1 + 4  # the initial value, then 1.0, Bad, 3.0 of item a (b disabled)


def _encoded(subscription: InternalSubscription) -> list[bytes]:
    return [struct_to_binary(n) for ns in subscription._triggered_datachanges.values() for n in ns]


async def test_queues_filters_and_publishing_at_once_as_asyncua() -> None:
    """``values.tell_monitored_items`` against asyncua's own callback for items of queue 1, 5
    and 0 (no limit), one with a deadband filter, one with the StatusValueTimestamp trigger, and a
    subscription that publishes at once (interval 0): the same notifications queued, the same
    ones published, in the same messages."""
    nodes = [ua.NodeId(name, 2) for name in "abcde"]
    deadband = ua.DataChangeFilter(
        Trigger=ua.DataChangeTrigger.StatusValue,
        DeadbandType=ua.DeadbandType.Absolute,
        DeadbandValue=0.5,
    )
    timestamps = ua.DataChangeFilter(Trigger=ua.DataChangeTrigger.StatusValueTimestamp)
    start = datetime(2026, 12, 7, tzinfo=UTC)
    bad = ua.StatusCode(ua.StatusCodes.BadCommunicationError)
    writes = [
        (index, number, status, start + timedelta(seconds=step))
        for step, (index, number, status) in enumerate(
            [(i, float(n), GOOD) for n in (1, 1, 1.2, 2, 3, 3) for i in range(5)]
            + [(i, None, bad) for i in (0, 1, 2, 4)]  # asyncua's deadband fails on Null
            + [(i, 4.0, GOOD) for i in range(5)]
        )
    ]
    for publishing_ms in (1000.0, 0.0):
        queued, published = [], []
        for fast in (False, True):
            sent: list[ua.PublishResult] = []
            aspace, subscription = await _watched(
                nodes,
                [1, 5, 0, 1, 1],
                [None, None, None, deadband, timestamps],
                publishing_ms,
                sent,
            )
            for index, number, status, when in writes:
                double = ua.VariantType.Double
                variant = ua.Variant() if number is None else scalar_variant(number, double)
                value = shared_value(variant, status, when, when)
                attribute = aspace[nodes[index]].attributes[ua.AttributeIds.Value]
                callbacks = attribute.datachange_callbacks
                if fast:
                    await run_later(tell_monitored_items(callbacks, value) or [])
                else:
                    for handle, callback in callbacks.items():
                        await callback(handle, value)
            queued.append(_encoded(subscription))
            published.append(
                [
                    [struct_to_binary(data) for data in result.NotificationMessage.NotificationData]
                    for result in sent
                ]
            )
        assert queued[0] == queued[1]
        assert published[0] == published[1]
        if publishing_ms:
            assert len(queued[0]) > len(nodes) and not published[0]
        else:
            assert len(published[0]) > len(nodes) and not queued[0]


@pytest.mark.parametrize(
    "when",
    [
        datetime(2026, 12, 7, 10, 11, 12, 131415, tzinfo=UTC),
        datetime(2026, 12, 7, 11, 11, 12, 131415, tzinfo=timezone(timedelta(hours=1))),
        datetime(2026, 12, 7, 10, 11, 12, 131415),
        datetime(1500, 1, 1, tzinfo=UTC),
        datetime(9999, 12, 31, 23, 59, 59, tzinfo=UTC),
        datetime(1970, 1, 1, tzinfo=UTC),
    ],
)
def test_a_remembered_timestamp_encodes_as_asyncua_encodes_it(when: datetime) -> None:
    asyncua_own = opcua_values._ASYNCUA_WIN_EPOCH
    assert ua.datetime_to_win_epoch is win_epoch  # installed on import
    for _ in range(2):  # computed, then remembered
        assert win_epoch(when) == asyncua_own(when)
    utc = when.astimezone(UTC) if when.tzinfo is not None else when
    assert win_epoch(utc) == asyncua_own(utc)
