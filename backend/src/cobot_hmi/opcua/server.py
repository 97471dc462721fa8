"""Layer: service (OPC UA). The OPC UA server's lifecycle: its own thread and event loop.

``OpcUaServer.start`` (on the service's web loop) starts a thread running an event loop of its
own (epoll, ``eventloop.precise_event_loop``) on which asyncua runs: the certificates
(``security``), the server's own checks of channels and sessions (``channel_policy``), the
companion models (``companion``), every robot's nodes
(``address_space``), the users (``auth``), the robots' writes (``writes``, ``sessions``), then
the listening socket; ``start`` returns once the server listens, or raises what stopped it
(``OpcUaStartError``: a taken port, an unreadable certificate …), so a misconfigured server
never passes unnoticed. Then, every monitoring period, a tick on a fixed grid of deadlines (a
late tick skips to the next one on the grid, never shifts it) updates the values of the robots
whose sampling is due from their newest frame (``values``, fed by ``feed``): a robot as often as
the fastest subscription watching one of its variables samples (asyncua samples an item at its
subscription's publishing interval; at most every tick), the robots spread over the ticks
(``SamplingPlan``); a robot nobody watches is updated when a Read or a new monitored item asks
for its values, so an answer is never older than a period (``freshen``). A historian sampling
every second costs a tenth of the updates of a screen sampling every 100 ms, and a server nobody
watches nearly nothing. Subscriptions start their publishing
cycles ``PUBLISH_AFTER_TICK`` of a period after a tick (``sessions``), so a publishing interval
that is a multiple of the monitoring period sends each tick's values right after it. Nothing
here runs on the cyclic thread or the web loop, and neither ever waits for this thread: frames
reach it through bounded queues, writes are handed to the web loop and awaited here.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import threading
import time
from collections.abc import Mapping
from concurrent.futures import Future
from pathlib import Path
from typing import Any, Final

from asyncua import ua

from cobot_hmi.eventloop import precise_event_loop
from cobot_hmi.opcua import security
from cobot_hmi.opcua.address_space import build
from cobot_hmi.opcua.auth import Permissions, UserManager
from cobot_hmi.opcua.build_info import build_info, describe
from cobot_hmi.opcua.channel_policy import EndpointGuard, GuardedServer
from cobot_hmi.opcua.companion import load
from cobot_hmi.opcua.feed import ServiceFeed
from cobot_hmi.opcua.opcua_settings import OpcUaSettings
from cobot_hmi.opcua.sessions import RobotInternalServer
from cobot_hmi.opcua.values import RobotValues
from cobot_hmi.opcua.writes import CommandWrites

log = logging.getLogger(__name__)

SERVER_NAME: Final = "cobot-hmi"
PRODUCT_URI: Final = "urn:cobot-hmi"
_JOIN_TIMEOUT_S: Final = 10.0
PUBLISH_AFTER_TICK: Final = 0.4
"""Where in the monitoring period a subscription's publishing cycle starts: after a tick's
updates (a few ms; tens on a busy machine), early enough that a value waits for its
notification only that long instead of up to a whole period (0.4: 40 ms at 10 Hz)."""


def watched_intervals(
    subscriptions: Mapping[int, Any], robots: Mapping[int, str], period_s: float
) -> dict[str, float]:
    """Each watched robot's sampling interval, s: the shortest publishing interval of the
    subscriptions with a monitored item on one of its variables (asyncua revises every item's
    sampling interval to its subscription's publishing interval), at least ``period_s``.
    ``robots``: the robots by namespace index. A robot nobody watches is not in the answer."""
    intervals: dict[str, float] = {}
    for subscription in subscriptions.values():
        interval_s = max(period_s, subscription.data.RevisedPublishingInterval / 1000.0)
        items = subscription.monitored_item_srv._monitored_items  # no public view of them
        for item in items.values():
            node = item.read_value_id.NodeId if item.read_value_id is not None else None
            name = robots.get(node.NamespaceIndex) if node is not None else None
            if name is not None and interval_s < intervals.get(name, math.inf):
                intervals[name] = interval_s
    return intervals


class SamplingPlan:
    """Which robots a tick updates: each watched robot every ``round(interval / period)``
    ticks (``watched_intervals``), the robots spread over the ticks; a robot nobody watches
    only when a Read or a new monitored item asks for its values (``OpcUaServer.freshen``).
    The intervals are found again only when the subscriptions changed (their ids, publishing
    intervals, items made and items held): a few attribute reads per subscription a tick."""

    def __init__(self, robots: Mapping[int, str], period_s: float) -> None:
        self.robots = robots
        self.period_s = period_s
        self.every: dict[str, int] = {}
        """Ticks between two updates of each watched robot."""
        self._signature: tuple[tuple[int, float, int, int], ...] = ()
        self._order = {name: index for index, name in enumerate(robots.values())}

    def refresh(self, subscriptions: Mapping[int, Any]) -> None:
        signature = tuple(
            (
                sid,
                sub.data.RevisedPublishingInterval,
                sub.monitored_item_srv._monitored_item_counter,
                len(sub.monitored_item_srv._monitored_items),
            )
            for sid, sub in subscriptions.items()
        )
        if signature == self._signature:
            return
        self._signature = signature
        intervals = watched_intervals(subscriptions, self.robots, self.period_s)
        self.every = {
            name: max(1, round(interval_s / self.period_s))
            for name, interval_s in intervals.items()
        }

    def due(self, name: str, tick: int) -> bool:
        every = self.every.get(name)
        return every is not None and (tick + self._order.get(name, 0)) % every == 0


def tick_deadline(deadline: float, now: float, period_s: float) -> float:
    """The deadline of the tick to run at ``now``: ``deadline``, or when more than a period
    late the last one on its grid before ``now`` (the missed ones skipped, the grid kept)."""
    late_s = now - deadline
    if late_s <= period_s:
        return deadline
    return deadline + period_s * math.floor(late_s / period_s)


def subscription_delay_s(now: float, next_tick: float, period_s: float) -> float:
    """Seconds from ``now`` to the next moment ``PUBLISH_AFTER_TICK`` of a period after a tick
    on the grid that has ``next_tick`` (in ``[0, period_s)``)."""
    start = next_tick - period_s * (1.0 - PUBLISH_AFTER_TICK)
    return (start - now) % period_s


class OpcUaStartError(RuntimeError):
    """The OPC UA server could not start; the message says why."""


class OpcUaServer:
    """See the module docstring. ``start`` and ``stop`` once each, on the web loop."""

    def __init__(self, settings: OpcUaSettings, state_dir: Path, feed: ServiceFeed) -> None:
        self.settings = settings
        self.feed = feed
        self.host, self.port = settings.opcua_bind
        self.certificates = security.Certificates(
            settings.opcua_pki_dir(state_dir), settings.opcua_trusted_dir(state_dir), self.host
        )
        self.period_s = 1.0 / settings.opcua_monitoring_hz
        self.values: dict[str, RobotValues] = {}
        self.routes: CommandWrites | None = None
        self.users: UserManager | None = None
        self.ticks = 0
        self.updates = 0
        """Robots' values updated (at ticks, for a Read, a new item or a write)."""
        self.late_ticks = 0
        """Ticks that started more than a period late (the thread starved)."""
        self.cpu_seconds = 0.0
        """CPU time of the server's thread since it started (asyncua and the updates), s."""
        self.startup_s: dict[str, float] = {}
        self._thread: threading.Thread | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stop: asyncio.Event | None = None
        self._next_tick = 0.0
        """The loop time of the next tick on the grid."""
        self._updated_at: dict[str, float] = {}
        """The loop time of each robot's last update."""
        self.plan: SamplingPlan | None = None
        self._subscriptions: Mapping[int, Any] = {}
        self._started: Future[None] = Future()

    @property
    def endpoint(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"opc.tcp://{host}:{self.port}"

    async def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="opcua server", daemon=True)
        self._thread.start()
        try:
            await asyncio.wrap_future(self._started)
        except Exception as error:
            await asyncio.to_thread(self._thread.join, _JOIN_TIMEOUT_S)
            raise OpcUaStartError(f"OPC UA server at {self.endpoint}: {error}") from error
        log.info(
            "%s (startup %s)",
            security.describe(
                self.host,
                self.port,
                loopback=self.settings.opcua_loopback,
                allow_no_security=self.settings.opcua_allow_no_security,
            ),
            ", ".join(f"{k} {v:.1f} s" for k, v in self.startup_s.items()),
        )

    async def stop(self) -> None:
        loop, stop, thread = self._loop, self._stop, self._thread
        if loop is not None and stop is not None and not loop.is_closed():
            with contextlib.suppress(RuntimeError):  # the loop closed meanwhile
                loop.call_soon_threadsafe(stop.set)
        if thread is not None:
            await asyncio.to_thread(thread.join, _JOIN_TIMEOUT_S)
        self._thread = None

    # ------------------------------------------------------------ the server's thread

    def _run(self) -> None:
        library_log = logging.getLogger("asyncua")
        if library_log.level == logging.NOTSET:  # its INFO is a line per session and request
            library_log.setLevel(logging.WARNING)
        loop = precise_event_loop()
        self._loop = loop
        asyncio.set_event_loop(loop)
        try:
            loop.run_until_complete(self._main())
        except Exception as error:  # before it started: start() raises it; after: logged
            if not self._started.done():
                self._started.set_exception(error)
            else:
                log.exception("the OPC UA server stopped")
        finally:
            loop.run_until_complete(loop.shutdown_asyncgens())
            loop.close()

    async def _main(self) -> None:
        self._stop = asyncio.Event()
        server = await self._make_server()
        try:
            self.feed.open()
            for values in self.values.values():
                await values.start()
            await server.start()
        except BaseException:
            self.feed.close()
            raise
        self._started.set_result(None)
        try:
            await self._ticks()
        finally:
            self.cpu_seconds = time.thread_time()
            self.feed.close()
            await server.stop()

    async def _make_server(self) -> GuardedServer:
        settings = self.settings
        mark = time.perf_counter()
        await asyncio.to_thread(self.certificates.ensure)
        self.users = UserManager(self.feed)
        offered = security.policies(
            loopback=settings.opcua_loopback, allow_no_security=settings.opcua_allow_no_security
        )
        validator = self.certificates.validator()
        guard = EndpointGuard(offered, validator)
        internal = RobotInternalServer(self.users, guard)
        server = GuardedServer(internal, guard)
        await server.init()
        self.startup_s["base address space"] = time.perf_counter() - mark
        server.set_endpoint(self.endpoint)
        server.set_server_name(SERVER_NAME)
        server.product_uri = PRODUCT_URI
        await server.set_application_uri(self.certificates.application_uri)
        await describe(server, build_info(PRODUCT_URI))
        server.set_security_policy(offered, permission_ruleset=Permissions())
        tokens: list[type] = [ua.UserNameIdentityToken]
        if self.feed.anonymous_reads:
            tokens.insert(0, ua.AnonymousIdentityToken)
        server.set_identity_tokens(tokens)
        await security.load_into(server, self.certificates)
        server.set_certificate_validator(validator)
        companion = await load(server)
        self.startup_s["companion models"] = companion.import_s
        nodes, build_s = await build(
            server, companion, self.feed.robot_names, writable=settings.opcua_writes
        )
        self.startup_s["robots"] = build_s
        self.values = {name: RobotValues(server, robot) for name, robot in nodes.items()}
        self.routes = CommandWrites(
            self.feed, nodes, enabled=settings.opcua_writes, written=self._refresh
        )
        internal.routes = self.routes
        internal.subscription_phase = self._subscription_phase
        internal.freshen = self.freshen
        self._subscriptions = internal.subscription_service.subscriptions
        by_namespace = {robot.namespace: name for name, robot in nodes.items()}
        self.plan = SamplingPlan(by_namespace, self.period_s)
        return server

    def _subscription_phase(self) -> float:
        now = asyncio.get_running_loop().time()
        return subscription_delay_s(now, self._next_tick, self.period_s)

    async def _refresh(self, name: str) -> None:
        """After a confirmed write: the robot's variables now, not at the next tick."""
        await self._update(name)

    async def _update(self, name: str) -> None:
        self._updated_at[name] = asyncio.get_running_loop().time()
        self.updates += 1
        await self.values[name].update(self.feed.sample(name))

    async def freshen(self, nodes: list[ua.NodeId]) -> None:
        """Before a Read or new monitored items: the robots of ``nodes`` whose values are more
        than a period old (nobody watches them, or slowly) updated first, so an answer or an
        item's first value is never older than a monitoring period."""
        plan = self.plan
        if plan is None:
            return
        stale_after = asyncio.get_running_loop().time() - self.period_s
        names = {plan.robots.get(node.NamespaceIndex) for node in nodes}
        for name in names:
            if name is not None and self._updated_at.get(name, -math.inf) < stale_after:
                await self._update(name)

    async def _ticks(self) -> None:
        """A tick per period, on absolute deadlines, until stopped: each robot's values
        updated when its sampling is due (``SamplingPlan``), the others' newest frame kept."""
        assert self._stop is not None and self.plan is not None
        plan = self.plan
        loop = asyncio.get_running_loop()
        deadline = loop.time()
        while not self._stop.is_set():
            on_grid = tick_deadline(deadline, loop.time(), self.period_s)
            if on_grid != deadline:  # skip the missed ticks instead of bursting
                self.late_ticks += 1
                deadline = on_grid
            plan.refresh(self._subscriptions)
            for name in self.values:
                try:
                    if plan.due(name, self.ticks):
                        await self._update(name)
                    else:
                        self.feed.keep_newest(name)
                except Exception:  # one robot's bug must not stop the others' values
                    log.exception("OPC UA: updating %s failed", name)
            self.ticks += 1
            self.cpu_seconds = time.thread_time()
            deadline += self.period_s
            self._next_tick = deadline
            try:
                async with asyncio.timeout_at(deadline):
                    await self._stop.wait()
            except TimeoutError:
                pass

    def counters(self) -> Mapping[str, float]:
        """For the bench and the log: ticks, CPU, writes, frames the queues dropped."""
        out: dict[str, float] = {
            "ticks": self.ticks,
            "updates": self.updates,
            "late_ticks": self.late_ticks,
            "cpu_seconds": self.cpu_seconds,
        }
        for name, values in self.values.items():
            out[f"{name}.values_written"] = values.writes
            out[f"{name}.frames_dropped"] = self.feed.dropped(name)
        return out
