"""Layer: composition. The settings of ``cobot-hmi serve``: the service's own parts
(``service.settings.ServiceSettings``) and those of the doors above it, the Sparkplug B edge
node (``sparkplug``: ``sparkplug.sparkplug_settings``) and the OPC UA server (``opcua``:
``opcua.opcua_settings``), which the service does not know. Keys stay flat as everywhere
(``ServiceSettings.flat_fields``): a field's name is its TOML key, ``COBOT_HMI_<NAME>`` its
environment variable and ``--name`` its flag, each routed to its part. Imports only settings
modules, so that a command reading settings loads neither paho-mqtt nor asyncua.
"""

from __future__ import annotations

from cobot_hmi.opcua.opcua_settings import OpcUaSettings
from cobot_hmi.service.service_settings import ServiceSettings, settings_part
from cobot_hmi.sparkplug.sparkplug_settings import SparkplugSettings


class HmiSettings(ServiceSettings):  # flags and TOML keys list the service's parts first
    """Everything ``cobot-hmi serve`` can be told: the service's parts and the doors'."""

    sparkplug: SparkplugSettings = settings_part(SparkplugSettings, "the Sparkplug B edge node")
    opcua: OpcUaSettings = settings_part(OpcUaSettings, "the OPC UA server")
