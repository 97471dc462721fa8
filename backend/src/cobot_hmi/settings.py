"""Layer: composition. The settings of ``cobot-hmi serve``: the service's own
(``service.settings.ServiceSettings``) and those of the doors above it, the Sparkplug B edge
node (``sparkplug.settings``) and the OPC UA server (``opcua.settings``), which the service does
not know. Keys stay flat as everywhere (``service.setting_fields``): a field's name is its TOML
key, ``COBOT_HMI_<NAME>`` its environment variable and ``--name`` its flag. Imports only
settings modules, so that a command reading settings loads neither paho-mqtt nor asyncua.
"""

from __future__ import annotations

from cobot_hmi.opcua.settings import OpcUaSettings
from cobot_hmi.service.settings import ServiceSettings
from cobot_hmi.sparkplug.settings import SparkplugSettings


class HmiSettings(  # flags and TOML keys list the service's first, then the last base's
    OpcUaSettings,
    SparkplugSettings,
    ServiceSettings,
):
    """Everything ``cobot-hmi serve`` can be told. Field names are the TOML keys."""

    # The service's (a settings class's: flat keys, frozen, nothing unknown), not a mixin's.
    model_config = ServiceSettings.model_config
