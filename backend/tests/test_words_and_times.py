"""Issue 38 (items 7, 8, 9), against the real service on loopback and its real SQLite file:
the alarm history says its values in words (JSON and CSV), never a robot state's number; a
search for "e-stop" or "estop" finds what "emergency" finds; a SAFE_OFF after a protective
stop's reset is that stop's consequence, not an emergency stop's cleared seconds before; and
every time a person reads (the CSV exports, the stream's hello that the pages write their times
by) is in the plant's time zone, the ``time_zone`` setting."""

from __future__ import annotations

import csv
import io
from datetime import datetime
from pathlib import Path
from typing import Any

import orjson
import pyarrow as pa
import pytest
from websockets.asyncio.client import connect

from cobot_hmi.codec import Frame, zero_frame
from cobot_hmi.history import export as history_export
from cobot_hmi.history.schema import SEQ, T2O_SEQUENCE, TIME
from cobot_hmi.service.alarms.engine import AlarmEngine
from cobot_hmi.service.alarms.persistence import AlarmChange
from cobot_hmi.service.plant_time import PLANT_ZONE, host_zone_name
from cobot_hmi.service.service_settings import ServiceSettings, SettingsError
from service_support import running_service, service_settings

pytestmark = pytest.mark.timeout(120)

ESTOP, SAFE_OFF, INTERRUPTED, STANDBY = 0, 2, 3, 13
BERLIN = "Europe/Berlin"
WINTER_S = 1_795_000_000.0  # 2026-11-18 11:06:40 UTC: Berlin is UTC+01:00
SUMMER_S = 1_783_000_000.0  # 2026-07-02 13:46:40 UTC: Berlin is UTC+02:00


def change(time_s: float, key: str, value: float | bool | None, message: str) -> AlarmChange:
    return AlarmChange(
        time=time_s,
        robot="robot",
        alarm_id=f"robot:{key}",
        key=key,
        name=key.replace("_", " ").capitalize(),
        priority="high",
        transition="activated",
        state="active_unacknowledged",
        shelved=False,
        message=message,
        value=value,
        label=None,
        tag=None,
        user=None,
        comment=None,
        record={},
    )


HISTORY = (
    change(WINTER_S, "emergency_stop", ESTOP, "robot state Emergency stop"),
    change(WINTER_S + 1, "safe_off", SAFE_OFF, "robot state Safe off (servo off)"),
    change(WINTER_S + 2, "protective_stop", STANDBY, "robot state now Standalone standby"),
    change(SUMMER_S, "motor_temperature.2", 81.25, "J 3 = 81.25 °C"),
    change(SUMMER_S + 1, "packet_loss", 12.0, "12 gaps in the last minute"),
)
WORDS = {
    "robot:emergency_stop": "Emergency stop",
    "robot:safe_off": "Safe off (servo off)",
    "robot:protective_stop": "Standalone standby",
    "robot:motor_temperature.2": "81.25 °C",
    "robot:packet_loss": "12 gaps/min",
}


def only_mine(items: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The rows this test wrote (the service may log a connection alarm of its own)."""
    return [i for i in items if i["alarm_id"] in WORDS]


async def test_alarm_history_values_and_times_in_words_and_the_plant_zone(
    robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    # The host runs UTC (or anything): the plant is in Berlin, and every time says so.
    settings = service_settings(robot_host, 44818, plc_host, tmp_path, time_zone=BERLIN)
    async with running_service(settings, wait_connected=False) as hmi:
        store = hmi.service.default_robot.alarm_store
        for row in HISTORY:
            store.submit(row)
        assert await store.flush()
        async with hmi.client() as client:
            page = (await client.get("/api/v1/alarms/history", params={"limit": 50})).json()
            text = (await client.get("/api/v1/alarms/history", params={"format": "csv"})).text
            async with connect(hmi.robot_ws_url("robot")) as stream:
                hello = orjson.loads(await stream.recv())
    items = only_mine(page["items"])
    assert {i["alarm_id"]: i["value_words"] for i in items} == WORDS
    assert {i["alarm_id"]: i["value"] for i in items}["robot:emergency_stop"] == ESTOP
    rows = only_mine(list(csv.DictReader(io.StringIO(text))))
    assert {r["alarm_id"]: r["value_words"] for r in rows} == WORDS
    # ISO 8601 in the plant's zone, with its offset, summer and winter alike.
    times = {r["alarm_id"]: r["time"] for r in rows}
    assert times["robot:emergency_stop"] == "2026-11-18T12:06:40.000000+01:00"
    assert times["robot:packet_loss"] == "2026-07-02T15:46:41.000000+02:00"
    assert datetime.fromisoformat(times["robot:packet_loss"]).timestamp() == SUMMER_S + 1
    # The pages are told the zone: they write every time in it (frontend lib/common/dates.ts).
    assert hello["type"] == "hello" and hello["time_zone"] == BERLIN


async def test_a_search_for_e_stop_finds_the_emergency_stop(
    robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    settings = service_settings(robot_host, 44818, plc_host, tmp_path)
    async with running_service(settings, wait_connected=False) as hmi:
        store = hmi.service.default_robot.alarm_store
        for row in HISTORY:
            store.submit(row)
        assert await store.flush()
        async with hmi.client() as client:
            found = {}
            for q in ("emergency", "e-stop", "estop", "E-Stop", "ESTOP"):
                answer = await client.get("/api/v1/alarms/history", params={"q": q})
                assert answer.status_code == 200, answer.text
                found[q] = {i["alarm_id"] for i in answer.json()["items"]}
    assert found["emergency"] == {"robot:emergency_stop"}
    assert all(ids == found["emergency"] for ids in found.values()), found


def test_an_unknown_time_zone_is_refused_and_empty_is_the_host_s() -> None:
    with pytest.raises((SettingsError, ValueError), match="IANA time zone"):
        ServiceSettings.from_keys(time_zone="Mars/Olympus_Mons")
    assert ServiceSettings().site.time_zone == ""
    PLANT_ZONE.use("")
    assert PLANT_ZONE.name == host_zone_name()


# --------------------------------------------------------------------------- item 8


def engine() -> AlarmEngine:
    return AlarmEngine(
        "left",
        clock=lambda: 1000.0,
        motor_temperature_c=80.0,
        motor_temperature_deadband_c=2.0,
        gap_rate_per_min=10.0,
        connection_delay_s=2.0,
        shelve_max_s=3600.0,
        consequence_window_s=5.0,
    )


def frame(state: int, **flags: bool) -> Frame:
    return zero_frame()._replace(robot_state=state, **flags)  # type: ignore[arg-type]


def test_safe_off_after_a_protective_stop_s_reset_is_that_stop_s_not_an_older_estop_s() -> None:
    """An e-stop reset at 2.0 s; a protective stop at 3.0 s, reset at 6.8 s: the SAFE_OFF then
    is the protective stop's consequence, though the e-stop cleared only 4.8 s before (within
    its window): a consequence is attributed to its most recent cause."""
    alarms = engine()
    alarms.observe(frame(ESTOP, emergency_stopped=True), 1.0)
    alarms.observe(frame(SAFE_OFF), 2.0)
    alarms.observe(frame(STANDBY, servo_on=True), 2.5)
    alarms.observe(frame(INTERRUPTED, safety_stopped=True, servo_on=True), 3.0)
    events = alarms.observe(frame(SAFE_OFF), 6.8) or []
    safe_off = next(e for e in events if e["alarm"]["key"] == "safe_off")  # type: ignore[index]
    assert safe_off["alarm"]["state"] == "suppressed"  # type: ignore[index]
    assert safe_off["alarm"]["suppressed_by"] == "left:protective_stop"  # type: ignore[index]
    assert safe_off["alarm"]["suppressed_by_name"] == "Protective stop"  # type: ignore[index]


def test_an_active_cause_is_named_before_one_that_cleared() -> None:
    """SAFE_OFF while an e-stop holds, 1.5 s after a protective stop cleared: the e-stop, which
    holds now, is its cause (an active cause is more recent than any that cleared)."""
    alarms = engine()
    alarms.observe(frame(INTERRUPTED, safety_stopped=True), 1.0)
    alarms.observe(frame(STANDBY), 2.0)
    alarms.observe(frame(STANDBY, emergency_stopped=True), 3.0)
    events = alarms.observe(frame(SAFE_OFF, emergency_stopped=True), 3.5) or []
    safe_off = next(e for e in events if e["alarm"]["key"] == "safe_off")  # type: ignore[index]
    assert safe_off["alarm"]["suppressed_by"] == "left:emergency_stop"  # type: ignore[index]


def test_the_history_export_s_csv_writes_its_times_in_the_plant_s_zone() -> None:
    """The recording's CSV export (``history/export.py``): in the plant's zone with its offset
    at each moment, summer and winter; in UTC as before (``Z``)."""
    micros = [int(WINTER_S * 1e6) + 123_456, int(SUMMER_S * 1e6)]
    table = pa.table(
        {
            TIME: pa.array(micros, pa.timestamp("us", tz="UTC")),
            SEQ: pa.array([1, 2], pa.int64()),
            T2O_SEQUENCE: pa.array([10, 11], pa.uint32()),
        }
    )

    def times(zone: str) -> list[str]:
        text = b"".join(history_export.export([table], "robot", [], "csv", zone=zone)).decode()
        return [row["time"] for row in csv.DictReader(io.StringIO(text))]

    assert times(BERLIN) == ["2026-11-18T12:06:40.123456+01:00", "2026-07-02T15:46:40.000000+02:00"]
    assert times("UTC") == ["2026-11-18T11:06:40.123456Z", "2026-07-02T13:46:40.000000Z"]
