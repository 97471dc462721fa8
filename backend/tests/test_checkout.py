"""Issue 23, the I/O checkout against the simulated robot behind the real EtherNet/IP target
(its control API sets the inputs) and the service on loopback: DI 5 is marked seen with the very
frame that first shows it, nobody touching the screen; an output passes only after the robot
confirmed it (switched through the write pipeline, with control); an analog input's two
captures; the CSV report lists every point; closing makes it read-only; every action is in
the audit trail; a restart keeps the checkout and goes on watching it."""

from __future__ import annotations

import csv
import functools
import io
from collections.abc import AsyncIterator, Sequence
from pathlib import Path
from typing import Any, Final

import httpx
import pytest

from cobot_hmi.service.commissioning.models import Checkout
from cobot_hmi.service.commissioning.points import CHECK_POINTS
from cobot_hmi.service.robots.frame_notifier import FrameRecord, Runs
from cobot_hmi.settings import HmiSettings
from emulator_harness import Emulator, running_emulator
from service_support import (
    OPERATOR,
    OPERATOR_2,
    VIEWER,
    Running,
    eventually_async,
    running_service,
    service_settings,
)

pytestmark = pytest.mark.timeout(180)

ROBOT: Final = "/api/v1/robots/robot"


@pytest.fixture
async def emu(robot_host: str, plc_host: str) -> AsyncIterator[Emulator]:
    async with running_emulator(robot_host, plc_host) as emulator_:
        yield emulator_


def settings_for(emu: Emulator, plc_host: str, tmp_path: Path) -> HmiSettings:
    return service_settings(
        emu.target.settings.host,
        emu.target.tcp_port,
        plc_host,
        tmp_path,
        alarm_connection_delay_s=600,
    )


class FrameLog:
    """A frame consumer of the test's own: every frame's number, time and DI 5."""

    name: Final = "test-frame-log"
    runs: Final = Runs.LOOP
    queue_frames: Final = 100_000

    def __init__(self) -> None:
        self.frames: list[tuple[int, float, bool]] = []

    def on_frames(self, robot: str, records: Sequence[FrameRecord]) -> None:
        self.frames.extend((r.seq, r.received_at_s, r.frame.controlbox_di[4]) for r in records)


async def get_checkout(client: httpx.AsyncClient, checkout_id: int) -> dict[str, Any]:
    answer = await client.get(f"{ROBOT}/checkouts/{checkout_id}")
    assert answer.status_code == 200, answer.text
    data: dict[str, Any] = answer.json()
    Checkout.model_validate(data)
    return data


def point(checkout: dict[str, Any], key: str) -> dict[str, Any]:
    found: dict[str, Any] = next(p for p in checkout["points"] if p["key"] == key)
    return found


async def seen(client: httpx.AsyncClient, checkout_id: int, key: str) -> bool:
    result: str = point(await get_checkout(client, checkout_id), key)["result"]
    return result == "seen"


async def test_checkout_inputs_outputs_report_and_close(
    emu: Emulator, plc_host: str, tmp_path: Path
) -> None:
    async with running_service(settings_for(emu, plc_host, tmp_path)) as hmi:
        robot = hmi.service.default_robot
        frame_log = FrameLog()
        robot.frames.add(frame_log)
        olivia = hmi.client(await hmi.login(OPERATOR))
        oscar = hmi.client(await hmi.login(OPERATOR_2))
        victor = hmi.client(await hmi.login(VIEWER))
        async with olivia, oscar, victor:
            refused = await victor.post(f"{ROBOT}/checkouts", json={})
            assert refused.status_code == 403
            started = await olivia.post(f"{ROBOT}/checkouts", json={})
            assert started.status_code == 201, started.text
            checkout_id = started.json()["id"]
            checkout = await get_checkout(victor, checkout_id)
            labels = {p["key"]: p["label"] for p in checkout["points"]}
            assert len(labels) == len(CHECK_POINTS) == 16 + 16 + 6 + 6 + 2 + 2 + 64 + 64
            assert labels["controlbox_di.4"] == "DI 5"
            assert labels["controlbox_do.2"] == "DO 3"
            assert labels["tool_do.1"] == "Tool DO 2"
            assert labels["analog_input.0"] == "AI 0"
            assert labels["bit_input_registers.12"] == "Register in 12"
            assert labels["bit_output_registers.12"] == "Register out 12"
            assert checkout["started_by"] == "olivia" and checkout["closed_at"] is None
            assert point(checkout, "controlbox_di.4")["result"] == "untested"

            # An input passes only once seen.
            early = await oscar.post(
                f"{ROBOT}/checkouts/{checkout_id}/points/controlbox_di.4/result",
                json={"result": "pass"},
            )
            assert early.status_code == 409 and "not seen" in early.json()["detail"]["reason"]

            # DI 5 set on the robot: seen with the frame that first shows it.
            await emu.post("/inputs", {"controlbox_di": {"4": True}})
            await eventually_async(lambda: seen(victor, checkout_id, "controlbox_di.4"))
            di5 = point(await get_checkout(victor, checkout_id), "controlbox_di.4")
            first_on = next(f for f in frame_log.frames if f[2])
            before_it = [f for f in frame_log.frames if f[0] == first_on[0] - 1]
            assert before_it and not before_it[0][2], "the frame before showed DI 5 off"
            assert di5["seen_at"] == pytest.approx(first_on[1], abs=1e-6)
            assert (di5["seen_before"], di5["seen_after"]) == (False, True)
            passed = await oscar.post(
                f"{ROBOT}/checkouts/{checkout_id}/points/controlbox_di.4/result",
                json={"result": "pass", "comment": "door switch wired"},
            )
            assert passed.status_code == 200, passed.text
            assert passed.json()["recorded_by"] == "oscar"

            # An output: pass only after the robot confirmed it.
            do3 = f"{ROBOT}/checkouts/{checkout_id}/points/controlbox_do.2"
            early = await olivia.post(f"{do3}/result", json={"result": "pass"})
            assert early.status_code == 409 and "confirmed" in early.json()["detail"]["reason"]
            no_control = await olivia.post(f"{do3}/switch", json={"value": True})
            assert no_control.status_code == 409, no_control.text
            assert (
                point(await get_checkout(victor, checkout_id), "controlbox_do.2")["switched_at"]
                is None
            )
            taken = await olivia.post(f"{ROBOT}/control/take", json={})
            assert taken.status_code == 200, taken.text
            switched = await olivia.post(f"{do3}/switch", json={"value": True})
            assert switched.status_code == 200, switched.text
            assert switched.json()["switched_value"] is True
            assert switched.json()["switched_by"] == "olivia"
            latest = robot.frames.latest
            assert latest is not None and latest.frame.controlbox_do[2] is True
            passed = await olivia.post(
                f"{do3}/result", json={"result": "pass", "comment": "valve moved"}
            )
            assert passed.status_code == 200 and passed.json()["result"] == "pass"
            failed = await olivia.post(
                f"{ROBOT}/checkouts/{checkout_id}/points/tool_do.1/result",
                json={"result": "fail", "comment": "no wire"},
            )
            assert failed.status_code == 200 and failed.json()["result"] == "fail"
            an_input = await olivia.post(
                f"{ROBOT}/checkouts/{checkout_id}/points/controlbox_di.5/switch",
                json={"value": True},
            )
            assert an_input.status_code == 409

            # AI 0: the values at two points the checker chooses.
            ai0 = f"{ROBOT}/checkouts/{checkout_id}/points/analog_input.0"
            for value in (4.0, 20.0):
                await emu.post("/inputs", {"analog_input": {"0": value}})
                await eventually_async(functools.partial(_ai0_is, hmi, value))
                captured = await oscar.post(f"{ai0}/capture", json={})
                assert captured.status_code == 200, captured.text
            ai = captured.json()
            assert [s["value"] for s in ai["samples"]] == pytest.approx([4.0, 20.0], abs=0.05)
            assert ai["result"] == "seen" and ai["samples"][0]["by"] == "oscar"

            # The report: every point, its result, who and when.
            report = await victor.get(f"{ROBOT}/checkouts/{checkout_id}/report.csv")
            assert report.status_code == 200
            assert report.headers["content-type"].startswith("text/csv")
            rows = list(csv.DictReader(io.StringIO(report.text)))
            assert [r["key"] for r in rows] == [p.key for p in CHECK_POINTS]
            by_label = {r["label"]: r for r in rows}
            assert by_label["DI 5"]["result"] == "pass"
            assert by_label["DI 5"]["seen_at"].startswith("20")
            assert by_label["DO 3"]["result"] == "pass"
            assert by_label["DO 3"]["recorded_by"] == "olivia"
            assert by_label["DO 3"]["comment"] == "valve moved"
            assert by_label["Tool DO 2"]["result"] == "fail"
            assert by_label["Register in 12"]["result"] == "untested"

            # Closed: read-only.
            closed = await olivia.post(f"{ROBOT}/checkouts/{checkout_id}/close", json={})
            assert closed.status_code == 200 and closed.json()["closed_by"] == "olivia"
            late = await oscar.post(
                f"{ROBOT}/checkouts/{checkout_id}/points/controlbox_di.6/result",
                json={"result": "fail"},
            )
            assert late.status_code == 409 and "read-only" in late.json()["detail"]["reason"]
            listed = (await victor.get(f"{ROBOT}/checkouts")).json()["items"]
            assert listed[0]["id"] == checkout_id and listed[0]["counts"]["pass"] == 2

            audit = (await olivia.get("/api/v1/audit?limit=100")).json()["items"]
            actions = [(row["action"], row["outcome"], row["user"]) for row in audit]
            assert ("checkout.start", "started", "olivia") in actions
            assert ("checkout.result", "recorded", "oscar") in actions
            assert ("checkout.result", "refused", "oscar") in actions
            assert ("checkout.capture", "captured", "oscar") in actions
            assert ("checkout.close", "closed", "olivia") in actions
            switch_rows = [r for r in audit if (r["origin"] or "").endswith("/switch")]
            assert {r["outcome"] for r in switch_rows} >= {"confirmed", "refused"}
            assert all(r["action"] == "write" for r in switch_rows)


async def _ai0_is(hmi: Running, value: float) -> bool:
    latest = hmi.service.default_robot.frames.latest
    return latest is not None and abs(latest.frame.analog_input[0] - value) < 0.05


async def test_a_restart_keeps_the_checkout_and_goes_on_watching(
    emu: Emulator, plc_host: str, tmp_path: Path
) -> None:
    settings = settings_for(emu, plc_host, tmp_path)
    async with (
        running_service(settings) as hmi,
        hmi.client(await hmi.login(OPERATOR)) as olivia,
    ):
        checkout_id = (await olivia.post(f"{ROBOT}/checkouts", json={})).json()["id"]
        await emu.post("/inputs", {"controlbox_di": {"5": True}})
        await eventually_async(lambda: seen(olivia, checkout_id, "controlbox_di.5"))
        failed = await olivia.post(
            f"{ROBOT}/checkouts/{checkout_id}/points/controlbox_do.0/result",
            json={"result": "fail", "comment": "no lamp"},
        )
        assert failed.status_code == 200
        before = await get_checkout(olivia, checkout_id)
    async with (
        running_service(settings) as hmi,
        hmi.client(await hmi.login(OPERATOR)) as olivia,
    ):
        after = await get_checkout(olivia, checkout_id)
        assert point(after, "controlbox_di.5") == point(before, "controlbox_di.5")
        assert point(after, "controlbox_do.0")["comment"] == "no lamp"
        assert after["started_at"] == before["started_at"]
        # Still watched after the restart: DI 7 seen without a request.
        await emu.post("/inputs", {"controlbox_di": {"6": True}})
        await eventually_async(lambda: seen(olivia, checkout_id, "controlbox_di.6"))


async def test_the_evidence_keeps_every_switch_a_fail_needs_a_comment_and_one_is_open(
    emu: Emulator, plc_host: str, tmp_path: Path
) -> None:
    """Issue 38: DO 3 confirmed on, passed, switched off: the point's evidence (its JSON and the
    report) still has the on with its confirmation time, then the off; a fail without a comment
    is refused (422); a second checkout is refused while one is open, naming it."""
    async with (
        running_service(settings_for(emu, plc_host, tmp_path)) as hmi,
        hmi.client(await hmi.login(OPERATOR)) as olivia,
        hmi.client(await hmi.login(OPERATOR_2)) as oscar,
    ):
        started = await olivia.post(f"{ROBOT}/checkouts", json={})
        assert started.status_code == 201, started.text
        checkout_id = started.json()["id"]
        second = await oscar.post(f"{ROBOT}/checkouts", json={})
        assert second.status_code == 409
        reason = second.json()["detail"]["reason"]
        assert f"checkout {checkout_id}" in reason and "open" in reason and "olivia" in reason
        assert [c["id"] for c in (await oscar.get(f"{ROBOT}/checkouts")).json()["items"]] == [
            checkout_id
        ]

        do3 = f"{ROBOT}/checkouts/{checkout_id}/points/controlbox_do.2"
        assert (await olivia.post(f"{ROBOT}/control/take", json={})).status_code == 200
        on = await olivia.post(f"{do3}/switch", json={"value": True})
        assert on.status_code == 200, on.text
        passed = await olivia.post(f"{do3}/result", json={"result": "pass", "comment": "valve"})
        assert passed.status_code == 200, passed.text
        off = await olivia.post(f"{do3}/switch", json={"value": False})
        assert off.status_code == 200, off.text
        do3_point = point(await get_checkout(oscar, checkout_id), "controlbox_do.2")
        switches = do3_point["switches"]
        assert [s["value"] for s in switches] == [True, False]
        assert all(s["by"] == "olivia" and s["latency_ms"] is not None for s in switches)
        assert switches[0]["time"] <= passed.json()["recorded_at"] <= switches[1]["time"]
        assert do3_point["result"] == "pass" and do3_point["switched_value"] is False

        report = await oscar.get(f"{ROBOT}/checkouts/{checkout_id}/report.csv")
        row = next(r for r in csv.DictReader(io.StringIO(report.text)) if r["label"] == "DO 3")
        on_words, off_words = row["switches"].split("; ")
        assert on_words.startswith("on confirmed 20") and on_words.endswith("by olivia")
        assert off_words.startswith("off confirmed 20")
        assert on_words.split()[2] < off_words.split()[2]  # ISO 8601 times, in order

        bare = await oscar.post(
            f"{ROBOT}/checkouts/{checkout_id}/points/tool_do.1/result", json={"result": "fail"}
        )
        assert bare.status_code == 422, bare.text
        assert "comment" in bare.json()["detail"]["reason"]
        blank = await oscar.post(
            f"{ROBOT}/checkouts/{checkout_id}/points/tool_do.1/result",
            json={"result": "fail", "comment": "   "},
        )
        assert blank.status_code == 422
        assert point(await get_checkout(oscar, checkout_id), "tool_do.1")["result"] == "untested"

        closed = await olivia.post(f"{ROBOT}/checkouts/{checkout_id}/close", json={})
        assert closed.status_code == 200
        again = await oscar.post(f"{ROBOT}/checkouts", json={})
        assert again.status_code == 201, again.text
        audit = (await olivia.get("/api/v1/audit?limit=100")).json()["items"]
        outcomes = {(r["action"], r["outcome"], r["user"]) for r in audit}
        assert ("checkout.start", "refused", "oscar") in outcomes
        assert ("checkout.result", "invalid", "oscar") in outcomes
        await olivia.post(f"{ROBOT}/control/release", json={})
