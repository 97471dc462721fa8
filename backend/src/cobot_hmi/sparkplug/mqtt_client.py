"""Layer: service (Sparkplug). The MQTT connection: paho-mqtt 2.x on a network thread of its own.

paho's thread (``loop_start``) does every socket operation, keep-alive and reconnect (backoff
from ``RECONNECT_MIN_S`` doubling to ``RECONNECT_MAX_S``), so neither the cyclic connection nor
the web event loop ever waits for the broker; ``publish`` only queues (paho is thread-safe).
MQTT 3.1.1, clean session, as Sparkplug B 3.0 asks of an edge node. ``mqtts://`` uses TLS with
the CA file (else the system's CAs) and optionally a client certificate; user and password go
in CONNECT.

Imports nothing of the project; the only module that imports paho-mqtt at run time.
"""

from __future__ import annotations

import ssl
from dataclasses import dataclass
from pathlib import Path
from typing import Final
from urllib.parse import urlsplit

import paho.mqtt.client as mqtt
from paho.mqtt.enums import CallbackAPIVersion

RECONNECT_MIN_S: Final = 1
RECONNECT_MAX_S: Final = 30
KEEPALIVE_S: Final = 30


@dataclass(frozen=True, slots=True)
class BrokerAddress:
    host: str
    port: int
    tls: bool

    @classmethod
    def parse(cls, url: str) -> BrokerAddress:
        """``mqtt://host[:1883]`` or ``mqtts://host[:8883]``; ``ValueError`` otherwise."""
        parts = urlsplit(url)
        if parts.scheme not in ("mqtt", "mqtts") or not parts.hostname:
            raise ValueError(f"an MQTT broker is mqtt://HOST:PORT or mqtts://HOST:PORT, got {url}")
        tls = parts.scheme == "mqtts"
        return cls(parts.hostname, parts.port or (8883 if tls else 1883), tls)

    def __str__(self) -> str:
        return f"{'mqtts' if self.tls else 'mqtt'}://{self.host}:{self.port}"


@dataclass(frozen=True, slots=True)
class ClientOptions:
    address: BrokerAddress
    client_id: str
    user: str = ""
    password: str = ""
    ca_file: Path | None = None
    client_cert: Path | None = None
    client_key: Path | None = None


def make_client(options: ClientOptions) -> mqtt.Client:
    """A configured client, not yet connected (``connect_async`` + ``loop_start`` do that)."""
    client = mqtt.Client(
        CallbackAPIVersion.VERSION2,
        client_id=options.client_id,
        clean_session=True,
        protocol=mqtt.MQTTv311,
    )
    if options.user:
        client.username_pw_set(options.user, options.password or None)
    if options.address.tls:
        client.tls_set(
            ca_certs=str(options.ca_file) if options.ca_file else None,
            certfile=str(options.client_cert) if options.client_cert else None,
            keyfile=str(options.client_key) if options.client_key else None,
            cert_reqs=ssl.CERT_REQUIRED,
        )
    client.reconnect_delay_set(RECONNECT_MIN_S, RECONNECT_MAX_S)
    return client
