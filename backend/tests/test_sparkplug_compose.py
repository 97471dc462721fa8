"""docker-compose.yml's optional MQTT broker for trying Sparkplug B (rendered by compose, as
tests/test_compose.py does): under its own profile, on the cell network, and the backend
publishing only when COBOT_HMI_MQTT_URL is given."""

from __future__ import annotations

import pytest

from test_compose import DOCKER, ROOT, _environment, _render

pytestmark = pytest.mark.skipif(DOCKER is None, reason="no docker client on this machine")


def test_the_sparkplug_broker_is_optional() -> None:
    default = _render()
    assert _environment(default["services"]["backend"]).get("COBOT_HMI_MQTT_URL", "") == ""
    rendered = _render({"COMPOSE_PROFILES": "sparkplug", "COBOT_HMI_MQTT_URL": "mqtt://b:1883"})
    broker = rendered["services"]["broker"]
    assert broker["profiles"] == ["sparkplug"]
    assert "cell" in broker["networks"]
    mounted = [str(v.get("source", v) if isinstance(v, dict) else v) for v in broker["volumes"]]
    assert any("mosquitto.conf" in v for v in mounted)
    assert (ROOT / "docker" / "mosquitto.conf").is_file()
    backend = _environment(rendered["services"]["backend"])
    assert backend["COBOT_HMI_MQTT_URL"] == "mqtt://b:1883"
