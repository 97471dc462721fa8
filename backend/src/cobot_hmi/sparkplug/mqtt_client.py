"""Layer: service (Sparkplug). The MQTT connection: paho-mqtt 2.x on a network thread of its own.

paho's thread (``loop_start``) does every socket operation, keep-alive and reconnect, so
neither the cyclic connection nor the web event loop ever waits for the broker; ``publish``
only queues (paho is thread-safe). The wait before each reconnect is ``ReconnectBackoff``'s
(``RECONNECT_MIN_S`` doubling to ``RECONNECT_MAX_S``, jittered, from the minimum again after a
connection), handed to paho before each of its waits.
MQTT 3.1.1, clean session, as Sparkplug B 3.0 asks of an edge node. ``mqtts://`` uses TLS with
the CA file (else the system's CAs) and optionally a client certificate; user and password go
in CONNECT.

Imports nothing of the project; the only module that imports paho-mqtt at run time.
"""

from __future__ import annotations

import random
import ssl
from dataclasses import dataclass
from pathlib import Path
from typing import Final
from urllib.parse import urlsplit

import paho.mqtt.client as mqtt
from paho.mqtt.enums import CallbackAPIVersion

RECONNECT_MIN_S: Final = 0.5
RECONNECT_MAX_S: Final = 5.0
"""A plant's broker restarts in seconds: no wait between two attempts is longer than this, so
the node is back within about this long of the broker's return."""
RECONNECT_JITTER: Final = 0.5
"""Each wait is drawn from [1 - this, 1] of its step, so the cells of a plant that lost the
same broker do not come back in lockstep."""
KEEPALIVE_S: Final = 30


class ReconnectBackoff:
    """The wait before each reconnect attempt: ``RECONNECT_MIN_S`` doubling up to
    ``RECONNECT_MAX_S``, jittered; ``connected`` starts it again from the minimum."""

    def __init__(self, rng: random.Random | None = None) -> None:
        self._rng = rng or random.Random()
        self._failures = 0

    def next_delay_s(self) -> float:
        step_s = min(RECONNECT_MAX_S, RECONNECT_MIN_S * 2.0 ** min(self._failures, 16))
        self._failures += 1
        return step_s * self._rng.uniform(1.0 - RECONNECT_JITTER, 1.0)

    def connected(self) -> None:
        """A CONNACK accepted the connection: the next loss starts from the minimum again."""
        self._failures = 0

    def arm(self, client: mqtt.Client) -> None:
        """Set the wait paho makes before its next attempt (call it on paho's thread, from
        ``on_disconnect`` or ``on_connect_fail``, which paho runs right before that wait).
        paho's own doubling has no jitter and keeps the longest wait it reached; with the
        minimum and maximum both set to this one, paho waits exactly this long."""
        delay_s = self.next_delay_s()
        # paho's annotation says int; its wait is float arithmetic (time.time() + delay).
        client.reconnect_delay_set(delay_s, delay_s)  # type: ignore[arg-type]


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
    # The first wait; each later one is set by ``ReconnectBackoff.arm`` before paho waits.
    client.reconnect_delay_set(RECONNECT_MIN_S, RECONNECT_MAX_S)  # type: ignore[arg-type]
    return client


def queued(info: mqtt.MQTTMessageInfo) -> bool:
    """``publish`` took the message (paho refuses it once it knows its connection is gone)."""
    return info.rc == mqtt.MQTT_ERR_SUCCESS
