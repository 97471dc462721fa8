"""Layer: plant (a door above the service). The host application's MQTT connection: paho-mqtt on
a thread of its own, over one or more broker URLs (a cluster's nodes, or a broker and its
standby): the first that answers; when it goes away, the next, in turn.

On each connection (Sparkplug 3.0, "Host Applications"): the will is the host's STATE
``{"online": false, "timestamp": T}`` (retained, QoS 1); once connected it subscribes (QoS 0) to
its own STATE topic and the Sparkplug namespace of its groups and, every subscription granted
within ``SUBSCRIBE_TIMEOUT_S`` (else the next broker), publishes STATE
``{"online": true, "timestamp": T}`` (retained, QoS 1), T the same in both: a will left from an
older connection never clears a newer birth. On a clean stop it publishes the offline STATE
itself, then disconnects. MQTT 3.1.1, clean session.

Imports ``sparkplug.mqtt_client`` (the client's making, addresses, backoff) and the host's STATE.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Any, Final

import paho.mqtt.client as mqtt

from cobot_hmi.plant.host import state_payload, state_topic
from cobot_hmi.sparkplug.mqtt_client import ClientOptions, ReconnectBackoff, make_client

log = logging.getLogger(__name__)

KEEPALIVE_S: Final = 10
"""Short: a broker node that dies without closing its sockets is noticed in 1.5 × this."""
CONNECT_TIMEOUT_S: Final = 3.0
SUBSCRIBE_TIMEOUT_S: Final = 5.0
READ_BURST: Final = 1000
"""Messages read at most between two calls of paho's ``loop`` (a fraction of a second's)."""
READ_BUFFER_BYTES: Final = 256 * 1024

MessageHandler = Callable[[str, bytes], None]
"""Called on the client's thread with each message's topic and payload."""
ConnectedHandler = Callable[[str], None]
"""Called on the client's thread with the broker's URL after each CONNACK."""


class FailoverClient:
    """One connection at a time to the first of ``options`` (one per broker URL) that answers."""

    def __init__(
        self,
        options: Sequence[ClientOptions],
        host_id: str,
        subscriptions: Sequence[str],
        on_message: MessageHandler,
        on_connected: ConnectedHandler,
    ) -> None:
        if not options:
            raise ValueError("the plant needs at least one broker URL")
        self._options = list(options)
        self._host_id = host_id
        self._subscriptions = list(subscriptions)
        self._on_message = on_message
        self._on_connected = on_connected
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._client: mqtt.Client | None = None
        self._lock = threading.Lock()
        self._backoff = ReconnectBackoff()
        self.connected_url: str | None = None
        self.connections = 0
        self.connections_lost = 0
        self.subscriptions_refused = 0
        self.state_timestamp_ms = 0
        self.messages = 0
        """Messages received (on the client's thread)."""

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="plant-mqtt", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """The offline STATE published (QoS 1, waited for briefly), then disconnect."""
        self._stop.set()
        with self._lock:
            client = self._client
        if client is not None and self.connected_url is not None:
            info = client.publish(
                state_topic(self._host_id),
                state_payload(False, self.state_timestamp_ms),
                qos=1,
                retain=True,
            )
            deadline = time.monotonic() + 2.0
            while not info.is_published() and time.monotonic() < deadline:
                time.sleep(0.02)
            client.disconnect()
        if self._thread is not None:
            self._thread.join(timeout=5.0)

    def publish(self, topic: str, payload: bytes, qos: int = 0, retain: bool = False) -> bool:
        """Queue a message on the current connection; ``False`` when there is none."""
        with self._lock:
            client = self._client
        if client is None or self.connected_url is None:
            return False
        return client.publish(topic, payload, qos=qos, retain=retain).rc == mqtt.MQTT_ERR_SUCCESS

    # ------------------------------------------------------------ the thread

    def _run(self) -> None:
        """Each URL in turn: a connection that ends moves on to the next at once; after a round
        in which none answered, the backoff's wait."""
        index = failed_in_a_row = 0
        count = len(self._options)
        while not self._stop.is_set():
            options = self._options[index % count]
            index += 1
            if self._session(options):
                self.connections_lost += 0 if self._stop.is_set() else 1
                self._backoff.connected()
                failed_in_a_row = 0
                continue
            failed_in_a_row += 1
            if failed_in_a_row % count == 0:
                self._stop.wait(self._backoff.next_delay_s())

    def _session(self, options: ClientOptions) -> bool:
        """One connection to one broker until it ends; whether it was ever established (its
        CONNACK and every SUBACK in time: a broker that accepts the connection but leaves a
        subscription unanswered, as NATS can while its JetStream re-elects after a node's loss,
        would let the plant hear nothing)."""
        client_id = f"{options.client_id}-{int(time.time() * 1000) % 100000}"
        client = make_client(replace(options, client_id=client_id))
        self.state_timestamp_ms = int(time.time() * 1000)
        client.will_set(
            state_topic(self._host_id),
            state_payload(False, self.state_timestamp_ms),
            qos=1,
            retain=True,
        )
        attempt = _Attempt()
        client.on_connect = lambda c, _u, _f, reason, _p: self._connected(c, reason, attempt)
        client.on_subscribe = lambda c, _u, mid, reasons, _p: self._subscribed(
            c, mid, reasons, attempt
        )
        client.on_message = lambda _c, _u, message: self._received(message)
        reads = _BufferedReads(client, self._publish_received)
        address = options.address
        try:
            client.connect(address.host, address.port, keepalive=KEEPALIVE_S)
        except (OSError, ValueError) as error:
            log.info("plant: broker %s not reachable: %s", address, error)
            return False
        with self._lock:
            self._client = client
        started = time.monotonic()
        try:
            while not self._stop.is_set():
                if client.loop(timeout=0.0 if reads.buffered else 0.2) != mqtt.MQTT_ERR_SUCCESS:
                    break
                if self._read_burst(client, reads) != mqtt.MQTT_ERR_SUCCESS:
                    break
                if not attempt.established.is_set() and attempt.overdue(started):
                    log.warning(
                        "plant: %s did not answer its CONNECT or SUBSCRIBE in time", address
                    )
                    self.subscriptions_refused += attempt.connack_at is not None
                    break
        finally:
            with self._lock:
                self._client = None
            self.connected_url = None
            if not self._stop.is_set():
                client.disconnect()
                log.warning("plant: connection to %s ended; trying the next broker", address)
        return attempt.established.is_set()

    def _received(self, message: mqtt.MQTTMessage) -> None:
        self.messages += 1
        self._on_message(message.topic, bytes(message.payload))

    def _publish_received(self, topic: str, payload: bytes) -> None:
        """A QoS 0 PUBLISH the reads took whole from the buffer (``_BufferedReads``)."""
        self.messages += 1
        self._on_message(topic, payload)

    def _read_burst(self, client: mqtt.Client, reads: _BufferedReads) -> int:
        """The messages already waiting, read without a ``select`` each: paho's ``loop`` reads
        one packet a call when nothing of QoS 1 or 2 is in flight, and a plant receives
        thousands a second. Stops once a read brought no message and nothing is left in the
        buffer (the next ``loop`` handles the rest), or after ``READ_BURST`` messages (so that
        ``loop`` still keeps the connection alive and writes: a read takes a whole buffer's
        messages, hundreds, and a plant behind its messages may hold each one a while, its
        inbox full; a burst counted in reads once kept ``loop`` away past the keepalive, and
        the broker closed the connection)."""
        first = self.messages
        while self.messages - first < READ_BURST:
            before = self.messages
            rc = client.loop_read()
            if rc != mqtt.MQTT_ERR_SUCCESS or (self.messages == before and not reads.buffered):
                return int(rc)
        return int(mqtt.MQTT_ERR_SUCCESS)

    def _subscribed(
        self, client: mqtt.Client, mid: int, reasons: list[Any], attempt: _Attempt
    ) -> None:
        """A subscription the broker refused: this connection would hear nothing, so it ends,
        and the next broker is tried. Once every one is granted: the STATE birth."""
        refused = [str(r) for r in reasons if r.is_failure]
        if refused:
            log.warning("plant: the broker refused a subscription (%s): reconnecting", refused)
            self.subscriptions_refused += 1
            client.disconnect()
            return
        attempt.pending.discard(mid)
        if attempt.pending or attempt.established.is_set():
            return
        client.publish(
            state_topic(self._host_id),
            state_payload(True, self.state_timestamp_ms),
            qos=1,
            retain=True,
        )
        self.connections += 1
        url = f"{client.host}:{client.port}"
        self.connected_url = url
        attempt.established.set()
        self._on_connected(url)

    def _connected(self, client: mqtt.Client, reason: Any, attempt: _Attempt) -> None:
        if reason.is_failure:
            log.warning("plant: broker refused the connection: %s", reason)
            return
        attempt.connack_at = time.monotonic()
        # QoS 0: what edge nodes publish is QoS 0 (births, data; their wills QoS 1 arrive as
        # 0), and a QoS 0 subscription needs no durable consumer of the broker's own (NATS's MQTT
        # keeps each QoS 1 subscription in JetStream, which a failover must first re-elect).
        for topic_filter in self._subscriptions:
            _, mid = client.subscribe(topic_filter, qos=0)
            if mid is not None:
                attempt.pending.add(mid)


class _BufferedReads:
    """paho's reads of one connection served from a buffer filled ``READ_BUFFER_BYTES`` at a
    time (paho asks for a packet's first byte, then its length byte by byte, then the rest: a
    socket call each, four a message, and every one lets go of the GIL, which the event loop's
    thread, busy with the messages before, then holds for up to the interpreter's switch
    interval). Its own reader (TLS's wants turned into paho's ``BlockingIOError``) fills it.

    When paho asks for a packet's first byte, every whole QoS 0 PUBLISH at the front of the
    buffer is taken first and handed to ``on_publish`` (topic, payload) as paho would hand it:
    that is nearly all a plant receives, and paho's way (its packet state in a dict, a message
    object, its topic decoded twice, a topic matcher, two locks) cost as much as the host's
    handling of the message. Anything else (another packet, one not yet whole) is paho's, from
    its first byte. MQTT 3.1.1 (no properties in a PUBLISH), as ``make_client`` connects."""

    def __init__(self, client: mqtt.Client, on_publish: Callable[[str, bytes], None]) -> None:
        self._client = client
        self._read = client._sock_recv  # paho's own, kept: its TLS and error handling
        self._on_publish = on_publish
        self._data = b""
        self._at = 0
        client._sock_recv = self.recv  # type: ignore[method-assign,assignment]  # paho reads so

    @property
    def buffered(self) -> int:
        return len(self._data) - self._at

    def recv(self, size: int) -> bytes:
        if size == 1 and self._client._in_packet["command"] == 0:  # a packet's first byte
            self._take_publishes()
        if self._at >= len(self._data):
            data = self._read(READ_BUFFER_BYTES)
            if not data:  # the connection closed: paho's own reading of it
                return data
            self._data, self._at = bytes(data), 0
            self._client._last_bytes_received = time.monotonic()  # as paho's reads note it
            if size == 1 and self._client._in_packet["command"] == 0:
                self._take_publishes()
                if self._at >= len(self._data):  # all taken: paho finds nothing more yet
                    raise BlockingIOError
        chunk = self._data[self._at : self._at + size]
        self._at += len(chunk)
        return chunk

    def _take_publishes(self) -> None:
        """The whole QoS 0 PUBLISH packets at the front of the buffer, handed on in order."""
        data, at, end = self._data, self._at, len(self._data)
        on_publish = self._on_publish
        while at < end and data[at] & 0xF6 == 0x30:  # PUBLISH, QoS 0 (DUP, RETAIN either way)
            length = shift = 0
            position = at + 1
            while position < end and position - at <= 4:
                byte = data[position]
                position += 1
                length |= (byte & 0x7F) << shift
                shift += 7
                if not byte & 0x80:
                    break
            else:
                break  # the length not whole yet (or over four bytes: paho's error to raise)
            if byte & 0x80 or position + length > end or length < 2:
                break  # not whole yet, or malformed: paho reads it
            topic_end = position + 2 + int.from_bytes(data[position : position + 2])
            if topic_end > position + length:
                break  # malformed: paho's error
            try:
                topic = data[position + 2 : topic_end].decode()
            except UnicodeDecodeError:
                break  # paho's way with it
            at = self._at = position + length
            on_publish(topic, data[topic_end:at])


class _Attempt:
    """One connection attempt's progress, on the client's thread."""

    def __init__(self) -> None:
        self.established = threading.Event()
        self.connack_at: float | None = None
        self.pending: set[int] = set()

    def overdue(self, started: float) -> bool:
        now = time.monotonic()
        if self.connack_at is None:
            return now - started > CONNECT_TIMEOUT_S
        return now - self.connack_at > SUBSCRIBE_TIMEOUT_S
