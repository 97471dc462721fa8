"""The alarm history as CSV against the real service: without ``limit``/``offset`` the whole
filtered history (more rows than a page and than one batch the stream reads at a time), newest
first, matching ``X-Total-Count``, read back by Python's csv; a transition written while the
CSV streams is not in it; ``limit``/``offset`` still ask for a page, and JSON stays paged."""

from __future__ import annotations

import csv
import io
from pathlib import Path

from cobot_hmi.service.alarms.persistence import (
    HISTORY_BATCH_ROWS,
    HISTORY_CSV_COLUMNS,
    AlarmChange,
    AlarmStore,
)
from service_support import running_service, service_settings

ROWS = 2 * HISTORY_BATCH_ROWS + 345
"""More than two batches of the stream, far more than a page."""


def change(i: int, robot: str) -> AlarmChange:
    """The ``i``-th synthetic transition: a high alarm on even ``i``, a medium one on odd."""
    high = i % 2 == 0
    return AlarmChange(
        time=1_800_000_000.0 + i,
        robot=robot,
        alarm_id=f"{robot}:{'protective_stop' if high else 'packet_loss'}",
        key="protective_stop" if high else "packet_loss",
        name="Protective stop" if high else "Packet loss",
        priority="high" if high else "medium",
        transition="activated" if i % 4 < 2 else "cleared",
        state="active_unacknowledged" if i % 4 < 2 else "returned_unacknowledged",
        shelved=False,
        message=f"change {i}, with a comma",
        value=None if high else float(i),
        label=None,
        tag=None,
        user=None,
        comment=None,
        record={},
    )


async def fill(store: AlarmStore, robot: str, first: int, count: int) -> None:
    for i in range(first, first + count):
        store.submit(change(i, robot))
    await store.flush()


def rows_of(text: str) -> list[dict[str, str]]:
    reader = csv.DictReader(io.StringIO(text))
    assert reader.fieldnames == list(HISTORY_CSV_COLUMNS)
    return list(reader)


async def test_alarm_history_csv_is_the_whole_filtered_history(
    robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    # No robot answers at robot_host: the history is the service's own, the robot not needed.
    settings = service_settings(robot_host, 44818, plc_host, tmp_path)
    async with running_service(settings, wait_connected=False) as hmi:
        robot = hmi.service.default_robot
        await robot.alarm_store.flush()  # whatever the start wrote (a connection alarm)
        await fill(robot.alarm_store, robot.name, 0, ROWS)
        async with hmi.client() as client:
            params = {"format": "csv", "priority": "high"}
            async with client.stream("GET", "/api/v1/alarms/history", params=params) as whole:
                chunks = whole.aiter_text()
                parts = [await anext(chunks)]
                # Written while the CSV streams: not in it (it is the history as asked).
                await fill(robot.alarm_store, robot.name, ROWS, 10)
                parts += [part async for part in chunks]
            # The link keeps trying the absent robot and may log another connection alarm at
            # any moment: the whole history and pages of it read with none in between.
            while True:
                everything = await client.get("/api/v1/alarms/history", params={"format": "csv"})
                page = await client.get(
                    "/api/v1/alarms/history", params={"format": "csv", "limit": 7, "offset": 3}
                )
                json_page = await client.get("/api/v1/alarms/history")
                again = await client.get("/api/v1/alarms/history", params={"format": "csv"})
                if again.text == everything.text:
                    break
    assert whole.status_code == 200
    assert whole.headers["content-type"].startswith("text/csv")
    assert "alarm-history.csv" in whole.headers["content-disposition"]
    high = rows_of("".join(parts))
    # Every high transition, once each, newest first; the total header says as many.
    expected = [i for i in reversed(range(ROWS)) if i % 2 == 0]
    synthetic = [r for r in high if r["message"].startswith("change ")]
    assert [int(r["message"].split()[1].rstrip(",")) for r in synthetic] == expected
    assert int(whole.headers["x-total-count"]) == len(high)
    assert all(r["priority"] == "high" for r in high)
    assert synthetic[0]["time"].startswith("2027-01-15T")  # ISO 8601
    ids = [int(r["id"]) for r in high]
    assert ids == sorted(ids, reverse=True) and len(set(ids)) == len(ids)
    all_rows = rows_of(everything.text)
    assert int(everything.headers["x-total-count"]) == len(all_rows) >= ROWS + 10
    assert {r["value"] for r in all_rows if r["message"] == "change 1, with a comma"} == {"1.0"}
    # A page when asked for one; JSON paged by default.
    assert [r["id"] for r in rows_of(page.text)] == [r["id"] for r in all_rows[3:10]]
    assert len(json_page.json()["items"]) == 100
    assert json_page.json()["total"] == len(all_rows)
