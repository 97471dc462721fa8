"""A robot's health as OPC UA variables in its vendor namespace, read with asyncua's client:
``Health`` (the robot's verdict, each joint's verdict and reason) and the joints' reducer life
used as Machinery lifetime counters (``LifetimeCounters``, DI's LifetimeVariableType: start 0,
limit 100, percent). The service's health reports are handed to its health service as its own
thread hands them (``Health.apply``), so the values come the way they come in production:
``health`` event, then the next monitoring tick; each written only when it changed."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pytest
from asyncua import Client, ua

from cobot_hmi.emulator.target import Target
from cobot_hmi.emulator.target_settings import TargetSettings
from cobot_hmi.service.health.service import LatestHealth, health_event
from conftest import _next_host, free_tcp_port
from service_support import cell_settings, running_service
from sparkplug_support import Panel
from waiting import eventually_async

ROBOT = "m1013"
MACHINERY_URI = "http://opcfoundation.org/UA/Machinery/"

pytestmark = [pytest.mark.timeout(300)]


def report(j3_verdict: str, j3_life: float) -> dict[str, Any]:
    return {
        "joints": [
            {
                "joint": j,
                "verdict": j3_verdict if j == 3 else "ok",
                "reason": "J3: friction 14 % above its baseline" if j == 3 else "fine",
                "life_used_percent": j3_life if j == 3 else 0.5,
            }
            for j in range(1, 7)
        ]
    }


async def test_health_variables_follow_the_health_events(plc_host: str, tmp_path: Path) -> None:
    host = _next_host()
    target = Target(TargetSettings(host=host, tcp_port=free_tcp_port(host)), Panel())
    await target.start()
    endpoint = f"opc.tcp://{plc_host}:{free_tcp_port(plc_host)}"
    settings = cell_settings(
        [(ROBOT, host, target.settings.tcp_port)],
        plc_host,
        tmp_path,
        opcua_url=endpoint,
        health_report_s=600.0,  # only this test's reports while it runs
    )
    try:
        async with running_service(settings) as running, Client(endpoint, timeout=60) as client:
            ns = await client.get_namespace_index(f"urn:cobot-hmi:robot:{ROBOT}")

            def node(path: str) -> Any:
                return client.get_node(ua.NodeId(f"{ROBOT}.{path}", ns))

            verdict = node("Health.J3.Verdict")
            life = node("LifetimeCounters.J3ReducerLifeUsed")
            first = await verdict.read_data_value(raise_on_bad_status=False)
            assert first.StatusCode.value == ua.StatusCodes.BadWaitingForInitialData

            # The shape: a Machinery lifetime counter of DI's LifetimeVariableType.
            counters = node("LifetimeCounters")
            counter_type = await counters.read_type_definition()
            machinery = await client.get_namespace_index(MACHINERY_URI)
            assert counter_type == ua.NodeId(1015, machinery)
            assert (await life.read_type_definition()).Identifier == 468
            assert await node("LifetimeCounters.J3ReducerLifeUsed.LimitValue").read_value() == 100
            assert await node("LifetimeCounters.J3ReducerLifeUsed.StartValue").read_value() == 0
            units = await node("LifetimeCounters.J3ReducerLifeUsed.EngineeringUnits").read_value()
            assert units.DisplayName.Text == "%"

            health = running.service.health
            health.apply(ROBOT, report("watch", 12.0), time.time())

            async def shows(node_: Any, value: object) -> bool:
                data = await node_.read_data_value(raise_on_bad_status=False)
                return bool(data.Value is not None and data.Value.Value == value)

            await eventually_async(lambda: shows(verdict, "watch"), timeout_s=30)
            assert await life.read_value() == pytest.approx(12.0)
            assert await node("Health.Verdict").read_value() == "watch"
            assert (await node("Health.J3.Reason").read_value()).startswith("J3: friction")
            assert await node("Health.J1.Verdict").read_value() == "ok"
            verdict_at = (await verdict.read_data_value()).SourceTimestamp

            # Life used moves, the verdict does not: only life used is written again.
            health.apply(ROBOT, report("watch", 12.5), time.time())
            await eventually_async(lambda: shows(life, 12.5), timeout_s=30)
            assert (await verdict.read_data_value()).SourceTimestamp == verdict_at
    finally:
        await target.stop()


def test_the_latest_health_events_are_handed_over_whole_never_changed() -> None:
    """``Health.latest`` is read from the OPC UA server's thread while the web loop publishes:
    what a reader holds (the snapshot, an event, its joints) never changes; a new event
    replaces the snapshot whole."""
    latest = LatestHealth()
    assert latest.get(ROBOT) is None and len(latest) == 0
    latest.publish(ROBOT, health_event(report("watch", 12.0), 1.0))
    held = latest[ROBOT]
    held_snapshot = dict(latest)
    latest.publish("h2017", health_event(report("ok", 1.0), 2.0))
    latest.publish(ROBOT, health_event(report("act", 12.5), 3.0))
    assert held["verdict"] == "watch" and held_snapshot == {ROBOT: held}
    assert latest[ROBOT]["verdict"] == "act" and list(latest) == [ROBOT, "h2017"]
    joints = held["joints"]
    assert isinstance(joints, tuple)
    with pytest.raises(TypeError):
        held["verdict"] = "ok"  # type: ignore[index]
    with pytest.raises(TypeError):
        joints[2]["verdict"] = "ok"
