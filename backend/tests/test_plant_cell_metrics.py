"""The cell's alarms, cycle times and health as Sparkplug metrics, on a real Mosquitto: our edge
node (the Sparkplug tests' cell: emulated robots, the service, its edge node) declares them in
its births and reports them by exception, read by an independent subscriber
(``mosquitto_support``), and ``cobot-hmi plant`` (a real process) shows them through its REST
API. Alarms come from the robots' own alarm engines (an emulated protective stop); cycles and
health are events published on the service's event bus, as the cycle meter and the health
monitor publish theirs."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pytest

from cobot_hmi.sparkplug.sparkplug_settings import SparkplugSettings
from mosquitto_support import Message, encode_command, needs_mosquitto
from plant_support import plant_process
from sparkplug_support import GROUP, NODE, STRING, Cell, cell

HOST_ID = "cobot-hmi-plant"
HMI_URL = "https://cell-7.example:8443/"
ROBOT = "m1013"

pytestmark = [needs_mosquitto, pytest.mark.timeout(120)]


def named(message: Message) -> dict[str, Any]:
    return {m.name: m for m in message.metrics if m.name}


def ddata_values(c: Cell, alias: int, after: int = 0) -> list[Any]:
    """The values of one metric in the robot's DDATA, in order (from message ``after`` on)."""
    messages = c.subscriber.snapshot()[after:]
    return [
        metric.value
        for m in messages
        if m.kind == "DDATA" and m.device == ROBOT
        for metric in m.metrics
        if metric.alias == alias and not metric.is_historical
    ]


def health_event(verdict: str, life_used: float) -> dict[str, object]:
    joints = [
        {
            "joint": j,
            "verdict": verdict if j == 3 else "ok",
            "reason": "J3: friction 14 % above its baseline" if j == 3 else "fine",
            "life_used_percent": life_used if j == 3 else 0.5,
        }
        for j in range(1, 7)
    ]
    return {"kind": "health", "time": time.time(), "verdict": verdict, "joints": joints}


def cycle_event(duration_s: float, interruption: str | None = None) -> dict[str, object]:
    start = time.time() - duration_s
    event: dict[str, object] = {
        "kind": "cycle",
        "time": start,
        "end": start + duration_s,
        "duration_s": duration_s,
    }
    if interruption:
        event["interruption"] = interruption
    return event


def test_the_hmi_url_defaults_to_the_services_own_address() -> None:
    settings = SparkplugSettings()
    assert settings.hmi_url("10.1.2.3", 8000, tls=False) == "http://10.1.2.3:8000/"
    assert settings.hmi_url("::1", 8443, tls=True) == "https://[::1]:8443/"
    assert "0.0.0.0" not in settings.hmi_url("0.0.0.0", 80, tls=False)
    named_url = SparkplugSettings(sparkplug_hmi_url=HMI_URL)
    assert named_url.hmi_url("0.0.0.0", 80, tls=False) == HMI_URL


async def test_births_declare_them_data_reports_changes_the_plant_shows_them(
    plc_host: str, tmp_path: Path
) -> None:
    async with (
        cell(
            tmp_path,
            plc_host,
            wait_births=False,
            sparkplug_primary_host=HOST_ID,
            sparkplug_hmi_url=HMI_URL,
            health_report_s=600.0,  # only this test's health events while it runs
        ) as c,
        plant_process(plc_host, tmp_path / "plant", [c.broker.url]) as plant,
    ):
        await c.subscriber.wait_for(
            lambda ms: {m.device for m in ms if m.kind == "DBIRTH"} >= {ROBOT}
        )
        [nbirth] = c.subscriber.of("NBIRTH")
        assert named(nbirth)["Node Info/HMI URL"].value == HMI_URL
        assert named(nbirth)["Node Info/HMI URL"].datatype == STRING
        birth = named(c.birth(ROBOT))
        # Every alarm of the robot's engine is declared, with its priority and words.
        assert birth["Alarm/emergency_stop/Active"].value is False
        assert birth["Alarm/emergency_stop/Priority"].value == "critical"
        assert birth["Alarm/emergency_stop/Text"].value == "Emergency stop"
        assert birth["Alarm/protective_stop/Active"].value is False
        assert (
            birth["Cycle/Last"].value is None and birth["Cycle/Last"].properties["engUnit"] == "s"
        )
        # Null until the service's health monitor (or this test) said something.
        assert birth["Health/J3/Verdict"].value in (None, "ok")
        assert birth["Health/J3/Life Used"].properties["engUnit"] == "%"
        aliases = c.aliases(ROBOT)

        # An alarm of the robot's own engine: a protective stop, and its clearing.
        c.panels[ROBOT].set(robot_state=3)
        active = aliases["Alarm/protective_stop/Active"]
        await c.subscriber.wait_for(lambda _: ddata_values(c, active) == [True])
        node = await plant.until(GROUP, NODE, lambda n: _device(n)["alarms_active"])
        assert node["hmi_url"] == HMI_URL
        alarm = next(a for a in _device(node)["alarms_active"] if a["alarm"] == "protective_stop")
        assert (alarm["priority"], alarm["text"]) == ("high", "Protective stop")
        c.panels[ROBOT].set(robot_state=13)
        await c.subscriber.wait_for(lambda _: ddata_values(c, active) == [True, False])

        # Cycles: the last and the mean; an interrupted one is no measure of the program.
        events = c.running.service.events
        events.publish(ROBOT, cycle_event(12.5))
        events.publish(ROBOT, cycle_event(3.0, "protective stop"))
        events.publish(ROBOT, cycle_event(13.5))
        last, average = aliases["Cycle/Last"], aliases["Cycle/Average"]
        await c.subscriber.wait_for(lambda _: ddata_values(c, last) == [12.5, 13.5])
        assert ddata_values(c, average) == [12.5, 13.0]

        # Health: by exception. The same report again changes nothing; life used moves by its
        # deadband.
        events.publish(ROBOT, health_event("watch", 12.0))
        verdict = aliases["Health/J3/Verdict"]
        await c.subscriber.wait_for(lambda _: ddata_values(c, verdict) == ["watch"])
        mark = len(c.subscriber.snapshot())
        events.publish(ROBOT, health_event("watch", 12.001))
        events.publish(ROBOT, cycle_event(14.5))  # a change after it, to know it was reported
        await c.subscriber.wait_for(lambda _: 14.5 in ddata_values(c, last, mark))
        health_aliases = {a for n, a in aliases.items() if n.startswith("Health/")}
        after = [
            metric.alias
            for m in c.subscriber.snapshot()[mark:]
            if m.kind == "DDATA"
            for metric in m.metrics
        ]
        assert not health_aliases & set(after)

        node = await plant.until(
            GROUP, NODE, lambda n: _device(n)["health"].get("J3/Verdict") == "watch"
        )
        device = _device(node)
        assert device["alarms_active"] == []
        assert (device["cycle_last_s"], device["cycle_average_s"]) == (14.5, pytest.approx(13.5))
        assert device["health"]["Verdict"] == "watch"
        assert float(device["health"]["J3/Life Used"]) == pytest.approx(12.0)
        assert device["health"]["J3/Reason"].startswith("J3: friction")

        # A rebirth: the births carry every value as it is now.
        births = len(c.subscriber.of("DBIRTH", ROBOT))
        c.subscriber.publish(
            f"spBv1.0/{GROUP}/NCMD/{NODE}",
            encode_command([("Node Control/Rebirth", None, 11, True)]),
        )
        await c.subscriber.wait_for(lambda _: len(c.subscriber.of("DBIRTH", ROBOT)) > births)
        birth = named(c.birth(ROBOT))
        assert birth["Cycle/Last"].value == 14.5
        assert birth["Health/J3/Verdict"].value == "watch"
        assert birth["Alarm/protective_stop/Active"].value is False


def _device(node: dict[str, Any]) -> dict[str, Any]:
    return next(d for d in node["devices"] if d["device"] == ROBOT)
