"""The plant's MQTT client (``plant/client.py``) on a real Mosquitto: every message a publisher
sends reaches the handler whole and in order, whether its reads take it whole from their buffer
(a QoS 0 PUBLISH, retained or not) or leave it to paho (a payload larger than the buffer, a
packet split across two of the buffer's fills)."""

from __future__ import annotations

import functools
import threading
from pathlib import Path

import paho.mqtt.client as mqtt
import pytest
from paho.mqtt.enums import CallbackAPIVersion

from cobot_hmi.plant.client import READ_BUFFER_BYTES, FailoverClient
from cobot_hmi.sparkplug.mqtt_client import BrokerAddress, ClientOptions
from mosquitto_support import mosquitto, needs_mosquitto
from waiting import eventually

pytestmark = [needs_mosquitto, pytest.mark.timeout(120)]

TOPIC = "spBv1.0/line-1/DDATA/cell-1/r1"
BATCH = 200


class Received:
    def __init__(self) -> None:
        self.messages: list[tuple[str, bytes]] = []
        self.lock = threading.Lock()
        self.connected = threading.Event()

    def on_message(self, topic: str, payload: bytes) -> None:
        with self.lock:
            self.messages.append((topic, payload))

    def has(self, count: int, sent: int) -> bool:
        """Has ``count`` messages, or every one sent and the one before them."""
        return self.count() >= min(count, 1 + sent)

    def count(self) -> int:
        with self.lock:
            return len(self.messages)


def payloads() -> list[bytes]:
    """Small and large (remaining lengths of one to three bytes, on each side of their
    limits), one larger than the read buffer."""
    sent = []
    for number in range(3000):
        size = (0, 1, 90, 127, 128, 700, 16_383, 16_384, 70_000)[number % 9]
        sent.append(number.to_bytes(4, "big") + bytes([number % 251]) * size)
    sent.insert(1500, b"big" + bytes(range(256)) * (READ_BUFFER_BYTES // 128))
    return sent


async def test_every_message_reaches_the_handler_whole_and_in_order(
    plc_host: str, tmp_path: Path
) -> None:
    async with mosquitto(plc_host, tmp_path) as broker:
        publisher = mqtt.Client(CallbackAPIVersion.VERSION2, protocol=mqtt.MQTTv311)
        publisher.max_queued_messages_set(0)
        publisher.connect(broker.host, broker.port)
        publisher.loop_start()
        retained = b"retained before the plant came"
        publisher.publish("spBv1.0/line-1/NBIRTH/cell-1", retained, qos=1, retain=True)
        received = Received()
        client = FailoverClient(
            [ClientOptions(BrokerAddress.parse(broker.url), "plant-test")],
            "plant-test",
            ["spBv1.0/line-1/#"],
            received.on_message,
            lambda _url: received.connected.set(),
        )
        client.start()
        try:
            await eventually(received.connected.is_set)
            await eventually(lambda: received.count() >= 1)
            sent = payloads()
            for start in range(0, len(sent), BATCH):  # a batch at a time: a QoS 0 subscriber
                for payload in sent[start : start + BATCH]:  # far behind loses messages
                    publisher.publish(TOPIC, payload, qos=0)
                await eventually(functools.partial(received.has, 1 + start + BATCH, len(sent)))
        finally:
            client.stop()
            publisher.disconnect()
            publisher.loop_stop()
    with received.lock:
        first, *rest = received.messages
    assert first == ("spBv1.0/line-1/NBIRTH/cell-1", retained)
    assert [topic for topic, _ in rest] == [TOPIC] * len(sent)
    assert [payload for _, payload in rest] == sent
    assert client.messages == 1 + len(sent)
