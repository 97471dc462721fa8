"""Issue 23, output presets against the simulated robot behind the real EtherNet/IP target and the
service on loopback: "All outputs off" exists without being made; a preset made by hand or from
the command image; what applying it changes; applying is ONE write through the write pipeline,
confirmed by the robot, all values or none, and audited; CSV export and import."""

from __future__ import annotations

from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any, Final

import httpx
import pytest

from cobot_hmi.service.commissioning.models import PresetChanges, PresetList
from emulator_harness import Emulator, running_emulator
from service_support import OPERATOR, VIEWER, running_service, service_settings

pytestmark = pytest.mark.timeout(180)

ROBOT: Final = "/api/v1/robots/robot"
JOB_3: Final = {
    "bit_input_registers.0": True,
    "bit_input_registers.1": True,
    "bit_input_registers.2": False,
    "bit_input_registers.3": False,
}


@pytest.fixture
async def emu(robot_host: str, plc_host: str) -> AsyncIterator[Emulator]:
    async with running_emulator(robot_host, plc_host) as emulator_:
        yield emulator_


async def presets(client: httpx.AsyncClient) -> dict[str, dict[str, Any]]:
    answer = await client.get(f"{ROBOT}/presets")
    assert answer.status_code == 200, answer.text
    PresetList.model_validate(answer.json())
    return {p["name"]: p for p in answer.json()["items"]}


async def command(client: httpx.AsyncClient) -> dict[str, Any]:
    answer = await client.get(f"{ROBOT}/command")
    assert answer.status_code == 200, answer.text
    image: dict[str, Any] = answer.json()["image"]
    return image


async def test_presets_save_apply_all_or_nothing_audited_export_import(
    emu: Emulator, plc_host: str, tmp_path: Path
) -> None:
    settings = service_settings(
        emu.target.settings.host,
        emu.target.tcp_port,
        plc_host,
        tmp_path,
        alarm_connection_delay_s=600,
    )
    async with running_service(settings) as hmi:
        olivia = hmi.client(await hmi.login(OPERATOR))
        victor = hmi.client(await hmi.login(VIEWER))
        async with olivia, victor:
            builtin = (await presets(victor))["All outputs off"]
            assert builtin["builtin"] is True
            assert builtin["items"]["controlbox_do.15"] is False
            assert builtin["labels"]["tool_do.5"] == "Tool DO 6"

            refused = await victor.post(f"{ROBOT}/presets", json={"name": "x", "items": JOB_3})
            assert refused.status_code == 403
            saved = await olivia.post(f"{ROBOT}/presets", json={"name": "Job 3", "items": JOB_3})
            assert saved.status_code == 200, saved.text
            assert saved.json()["labels"]["bit_input_registers.1"] == "Register in 1"
            bad = await olivia.post(
                f"{ROBOT}/presets",
                json={"name": "bad", "items": {"controlbox_do.0": True, "controlbox_do.16": True}},
            )
            assert bad.status_code == 422 and bad.json()["detail"]["field"] == "controlbox_do.16"
            builtin_name = await olivia.post(
                f"{ROBOT}/presets", json={"name": "All outputs off", "items": JOB_3}
            )
            assert builtin_name.status_code == 409
            assert set(await presets(victor)) == {"All outputs off", "Job 3"}

            # What it would change, then applying it needs control.
            changes = (await victor.get(f"{ROBOT}/presets/Job 3/changes")).json()
            PresetChanges.model_validate(changes)
            assert [c["label"] for c in changes["changes"]] == ["Register in 0", "Register in 1"]
            no_control = await olivia.post(f"{ROBOT}/presets/Job 3/apply", json={})
            assert no_control.status_code == 409
            assert (await command(olivia))["bit_input_registers"][:4] == [False] * 4
            assert (await olivia.post(f"{ROBOT}/control/take", json={})).status_code == 200
            applied = await olivia.post(f"{ROBOT}/presets/Job 3/apply", json={})
            assert applied.status_code == 200, applied.text
            assert (await command(olivia))["bit_input_registers"][:4] == [True, True, False, False]

            # All or nothing: AO 0 at 12 (mA, its type now) with DO 1 on, valid when saved...
            both = {"analog_output.0": 12.0, "controlbox_do.0": True}
            saved = await olivia.post(f"{ROBOT}/presets", json={"name": "AO and DO", "items": both})
            assert saved.status_code == 200, saved.text
            # ... not once AO 0 is a voltage (0–10 V): refused whole, DO 1 stays off.
            volts = await olivia.patch(
                f"{ROBOT}/command",
                json={"analog_output_type": {"0": 1}, "analog_output": {"0": 5.0}},
            )
            assert volts.status_code == 200, volts.text
            whole = await olivia.post(f"{ROBOT}/presets/AO and DO/apply", json={})
            assert whole.status_code == 422, whole.text
            image = await command(olivia)
            assert image["controlbox_do"][0] is False and image["analog_output"][0] == 5.0
            frame = (await olivia.get(f"{ROBOT}/frame")).json()["frame"]
            assert frame["controlbox_do"][0] is False

            # From the command image: the registers as they are now.
            from_image = await olivia.post(
                f"{ROBOT}/presets",
                json={"name": "Now", "from_image": True, "fields": ["bit_input_registers"]},
            )
            assert from_image.status_code == 200, from_image.text
            items = from_image.json()["items"]
            assert len(items) == 64 and items["bit_input_registers.1"] is True

            # "All outputs off", made by nobody, applied.
            on = await olivia.patch(f"{ROBOT}/command", json={"controlbox_do": {"3": True}})
            assert on.status_code == 200
            off = await olivia.post(f"{ROBOT}/presets/All outputs off/apply", json={})
            assert off.status_code == 200, off.text
            assert [c["key"] for c in off.json()["changes"]] == ["controlbox_do.3"]
            assert (await command(olivia))["controlbox_do"] == [False] * 16

            audit = (await olivia.get("/api/v1/audit?limit=100")).json()["items"]
            applies = [r for r in audit if (r["origin"] or "").endswith("/apply")]
            job = [r for r in applies if "Job%203" in r["origin"] or "Job 3" in r["origin"]]
            assert {r["outcome"] for r in job} == {"confirmed", "refused"}
            confirmed = next(r for r in job if r["outcome"] == "confirmed")
            assert confirmed["action"] == "write" and sorted(confirmed["fields"]) == sorted(JOB_3)
            assert any(r["outcome"] == "invalid" for r in applies)
            saves = [r for r in audit if r["action"] == "preset.save" and r["outcome"] == "saved"]
            assert len(saves) == 3
            assert any(
                r["action"] == "preset.save"
                and r["outcome"] == "invalid"
                and "out of range" in (r["reason"] or "")
                for r in audit
            )

            # Export as CSV, delete, import back (checked against the image as it is now: the
            # AO preset's 12 would be refused, and with it the whole import).
            assert (await olivia.delete(f"{ROBOT}/presets/AO and DO")).status_code == 200
            exported = await victor.get(f"{ROBOT}/presets.csv")
            assert exported.status_code == 200
            assert "Job 3,bit_input_registers.1,Register in 1,1" in exported.text
            deleted = await olivia.delete(f"{ROBOT}/presets/Job 3")
            assert deleted.status_code == 200 and "Job 3" not in {
                p["name"] for p in deleted.json()["items"]
            }
            assert (await olivia.delete(f"{ROBOT}/presets/All outputs off")).status_code == 409
            imported = await olivia.post(f"{ROBOT}/presets/import", json={"csv": exported.text})
            assert imported.status_code == 200, imported.text
            again = await presets(victor)
            assert again["Job 3"]["items"] == JOB_3
            json_import = await olivia.post(
                f"{ROBOT}/presets/import",
                json={"items": [{"name": "Job 4", "items": {"tool_do.0": True}}]},
            )
            assert json_import.status_code == 200
            assert (await presets(victor))["Job 4"]["items"] == {"tool_do.0": True}
