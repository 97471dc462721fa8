"""Layer: plant (a door above the service). The plant's REST API, ``/api/v1/plant/...``
(docs/api.md "The plant"): every edge node and device at a glance, the plant's alarm list with
ISA-18.2 figures per cell, a metric's trend from the history, the connection's status. Reading
is open unless ``view_requires_login`` (the service's viewer gate); the answers' models are
here, in the plant app's own OpenAPI document.
"""

from __future__ import annotations

import asyncio
import time
from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Annotated, Final
from zoneinfo import ZoneInfo

from fastapi import APIRouter, Query, Request
from fastapi.responses import Response
from pydantic import BaseModel, TypeAdapter

from cobot_hmi.layout import robot_state_name
from cobot_hmi.plant import trends
from cobot_hmi.plant.model import (
    AREA_METRIC,
    CYCLE_AVERAGE,
    CYCLE_LAST,
    HMI_URL_METRIC,
    STATE_METRIC,
    DeviceView,
    NodeView,
    alarm_figures,
    shift_figures,
    state_group,
)
from cobot_hmi.plant.peers import PeerError, Peers
from cobot_hmi.plant.recorder import MetricKey, PlantRecorder, Point
from cobot_hmi.plant.runtime import PlantRuntime
from cobot_hmi.service.api.deps import ViewerDep
from cobot_hmi.service.errors import ApiError
from cobot_hmi.service.plant_time import host_zone_name

router = APIRouter(prefix="/api/v1/plant", tags=["plant"])

MAX_ALARMS: Final = 5000
DAY_MS: Final = 86_400_000


class ActiveAlarmModel(BaseModel):
    alarm: str
    priority: str
    text: str
    since: float
    """Epoch seconds."""


class DeviceModel(BaseModel):
    device: str
    online: bool
    since: float
    state: str | None
    state_group: str | None
    """running, standby, stopped or error."""
    alarms_active: list[ActiveAlarmModel]
    cycle_last_s: float | None
    cycle_average_s: float | None
    health: dict[str, str]


class NodeModel(BaseModel):
    group: str
    node: str
    online: bool
    since: float
    bd_seq: int | None
    hmi_url: str | None
    area: str | None
    devices: list[DeviceModel]
    peer: str | None = None
    """The plant process that follows this node: null this one, else its URL (``--peer``)."""


class AlarmTransitionModel(BaseModel):
    time: float
    group: str
    node: str
    device: str
    alarm: str
    active: bool
    priority: str
    text: str
    historical: bool


class CellFiguresModel(BaseModel):
    group: str
    node: str
    alarms_per_10_min: float
    flood: bool
    peak_per_10_min: int
    bad_actors: list[tuple[str, str, int]]
    """(device, alarm, activations), the ten most frequent."""


class AlarmsAnswer(BaseModel):
    transitions: list[AlarmTransitionModel]
    """Newest first."""
    figures: list[CellFiguresModel]


class TrendPoint(BaseModel):
    time: float
    value: float | None
    text: str | None
    historical: bool


class ShiftAnswer(BaseModel):
    seconds: dict[str, float]
    """Seconds in each state group (running, standby, stopped, error) and ``unknown``."""
    cycles: int
    mean_cycle_s: float | None


class StatusAnswer(BaseModel):
    host_id: str
    broker: str | None
    connections: int
    connections_lost: int
    subscriptions_refused: int
    messages: int
    rebirths: dict[str, int]
    rebirths_held: int
    stale_deaths: int
    bad_messages: int
    history_rows: int


def _runtime(request: Request) -> PlantRuntime:
    runtime: PlantRuntime = request.app.state.service
    return runtime


def _number(value: object) -> float | None:
    return float(value) if isinstance(value, int | float) and not isinstance(value, bool) else None


def _device(view: DeviceView) -> DeviceModel:
    state = view.state()
    return DeviceModel(
        device=view.name,
        online=view.online,
        since=view.since_ms / 1000,
        state=state,
        state_group=state_group(state),
        alarms_active=[
            ActiveAlarmModel(
                alarm=a.alarm, priority=a.priority, text=a.text, since=a.since_ms / 1000
            )
            for a in view.alarms_active()
        ],
        cycle_last_s=_number(view.value(CYCLE_LAST)),
        cycle_average_s=_number(view.value(CYCLE_AVERAGE)),
        health=view.health(),
    )


def _node(view: NodeView, devices: list[DeviceModel]) -> NodeModel:
    return NodeModel(
        group=view.group,
        node=view.node,
        online=view.online,
        since=view.since_ms / 1000,
        bd_seq=view.bd_seq,
        hmi_url=view.text(HMI_URL_METRIC),
        area=view.text(AREA_METRIC),
        devices=devices,
    )


NODES_CACHE_S: Final = 0.2
"""How long one ``/nodes`` answer serves every page that asks again (a wall display, phones,
the control room): its cost, every device of the plant, is paid at most this often."""


@dataclass
class _Answered:
    at_s: float
    body: bytes


NodesCache = dict[tuple[str | None, str | None, str | None, bool], _Answered]


def _matching(
    node: NodeModel, group: str | None, area: str | None, state: str | None
) -> NodeModel | None:
    """A peer's node as the filters leave it (as ``_local_nodes`` filters this process's)."""
    if (group is not None and node.group != group) or (area is not None and node.area != area):
        return None
    if state is None:
        return node
    devices = [d for d in node.devices if state in (d.state, d.state_group)]
    return node.model_copy(update={"devices": devices}) if devices else None


def _peer_nodes(
    peers: Peers, known: set[tuple[str, str]], filters: tuple[str | None, str | None, str | None]
) -> list[NodeModel]:
    """Every peer's nodes as last answered (a node this process follows too: its own kept)."""
    found = []
    for peer in peers.peers:
        try:
            nodes = _NODE_LIST.validate_python(peer.nodes)
        except ValueError:
            continue
        for node in nodes:
            if (node.group, node.node) in known:
                continue
            known.add((node.group, node.node))
            matching = _matching(node.model_copy(update={"peer": peer.url}), *filters)
            if matching is not None:
                found.append(matching)
    return found


def _nodes_answer(
    runtime: PlantRuntime,
    peers: Peers | None,
    group: str | None,
    area: str | None,
    state: str | None,
) -> bytes:
    answer = _local_nodes(runtime, group, area, state)
    if peers is not None and peers.peers:
        known = set(runtime.host.nodes)
        answer += _peer_nodes(peers, known, (group, area, state))
        answer.sort(key=lambda n: (n.group, n.node))
    return _NODE_LIST.dump_json(answer)


def _peers(request: Request) -> Peers | None:
    found: Peers | None = getattr(request.app.state, "plant_peers", None)
    return found


def _local_nodes(
    runtime: PlantRuntime, group: str | None, area: str | None, state: str | None
) -> list[NodeModel]:
    answer = []
    for (node_group, _), view in sorted(runtime.host.nodes.items()):
        if (group is not None and node_group != group) or (
            area is not None and view.text(AREA_METRIC) != area
        ):
            continue
        devices = [_device(d) for _, d in sorted(view.devices.items())]
        if state is not None:
            devices = [d for d in devices if state in (d.state, d.state_group)]
            if not devices:
                continue
        answer.append(_node(view, devices))
    return answer


_NODE_LIST: Final = TypeAdapter(list[NodeModel])


@router.get(
    "/nodes",
    summary="Every edge node seen, with its devices (robots)",
    response_model=list[NodeModel],
)
async def nodes(
    request: Request,
    _viewer: ViewerDep,
    area: Annotated[str | None, Query(description="only nodes of this area")] = None,
    state: Annotated[
        str | None, Query(description="only devices in this state group or state")
    ] = None,
    group: Annotated[str | None, Query(description="only this Sparkplug group")] = None,
    local: Annotated[
        bool, Query(description="only this process's nodes, not its peers' (a peer asks so)")
    ] = False,
) -> Response:
    # Built from the models as they are (never validated again: they are ours), and the same
    # answer given to every page asking within NODES_CACHE_S.
    runtime = _runtime(request)
    state_of_app = request.app.state
    if not hasattr(state_of_app, "plant_nodes_cache"):
        state_of_app.plant_nodes_cache = {}
    answers: NodesCache = state_of_app.plant_nodes_cache  # this app's (its runtime's) own
    key = (group, area, state, local)
    now_s = time.monotonic()
    cached = answers.get(key)
    if cached is None or now_s - cached.at_s > NODES_CACHE_S:
        if len(answers) > 64:  # one plant's few filters; never grows without bound
            answers.clear()
        peers = None if local else _peers(request)
        body = _nodes_answer(runtime, peers, group, area, state)
        cached = answers[key] = _Answered(now_s, body)
    return Response(cached.body, media_type="application/json")


@router.get("/alarms", summary="The plant's alarm transitions and ISA-18.2 figures per cell")
async def alarms(
    request: Request,
    _viewer: ViewerDep,
    since: Annotated[float | None, Query(description="epoch s (default: a day ago)")] = None,
    until: Annotated[float | None, Query(description="epoch s (default: now)")] = None,
    limit: Annotated[int, Query(ge=1, le=MAX_ALARMS)] = 500,
    local: Annotated[bool, Query(description="only this process's, not its peers'")] = False,
) -> AlarmsAnswer:
    end_ms = int((until if until is not None else time.time()) * 1000)
    start_ms = int(since * 1000) if since is not None else end_ms - DAY_MS
    answer = _local_alarms(_runtime(request), start_ms, end_ms, limit)
    peers = None if local else _peers(request)
    if peers is None or not peers.peers:
        return answer
    range_ = {"since": str(start_ms / 1000), "until": str(end_ms / 1000), "limit": str(limit)}
    for peer, found in await peers.ask_all("/api/v1/plant/alarms", range_):
        try:
            theirs = AlarmsAnswer.model_validate(found)
        except ValueError:
            peer.failed("not an alarm list")
            continue
        answer.transitions += theirs.transitions
        answer.figures += theirs.figures
    answer.transitions.sort(key=lambda t: t.time, reverse=True)
    del answer.transitions[limit:]
    answer.figures.sort(key=lambda f: (f.group, f.node))
    return answer


def _local_alarms(runtime: PlantRuntime, start_ms: int, end_ms: int, limit: int) -> AlarmsAnswer:
    transitions = runtime.host.alarms.between(start_ms, end_ms)
    figures = alarm_figures(transitions, start_ms, end_ms)
    return AlarmsAnswer(
        transitions=[
            AlarmTransitionModel(
                time=t.time_ms / 1000,
                group=t.group,
                node=t.node,
                device=t.device,
                alarm=t.alarm,
                active=t.active,
                priority=t.priority,
                text=t.text,
                historical=t.historical,
            )
            for t in reversed(transitions[-limit:])
        ],
        figures=[
            CellFiguresModel(
                group=f.group,
                node=f.node,
                alarms_per_10_min=f.alarms_per_10_min,
                flood=f.flood,
                peak_per_10_min=f.peak_per_10_min,
                bad_actors=f.bad_actors,
            )
            for f in figures
        ],
    )


@router.get("/trend", summary="One metric of one device over a range, from the plant's history")
async def trend(
    request: Request,
    _viewer: ViewerDep,
    *,
    group: str,
    node: str,
    metric: str,
    since: Annotated[float, Query(description="epoch s")],
    until: Annotated[float | None, Query(description="epoch s (default: now)")] = None,
    device: Annotated[str, Query(description="empty: the node's own metric")] = "",
    points: Annotated[
        int | None,
        Query(
            ge=1,
            le=trends.MAX_BUCKETS,
            description="decimated to this many equal spans of the range, each its first, "
            "lowest, highest and last value (default: every value)",
        ),
    ] = None,
    local: Annotated[bool, Query(description="only this process's history")] = False,
) -> list[TrendPoint]:
    end_ms = int((until if until is not None else time.time()) * 1000)
    runtime = _runtime(request)
    peers = None if local or (group, node) in runtime.host.nodes else _peers(request)
    owner = None if peers is None else peers.owner(group, node)
    if peers is not None and owner is not None:
        # A peer's cell: its history is that peer's (asked as the page would, bounded).
        asked = {"group": group, "node": node, "device": device, "metric": metric}
        asked |= {"since": str(since), "until": str(end_ms / 1000)}
        if points is not None:
            asked["points"] = str(points)
        try:
            return _TREND.validate_python(await peers.ask(owner, "/api/v1/plant/trend", asked))
        except (PeerError, ValueError) as error:
            reason = f"the plant process {owner.url} that follows {node}: {error}"
            raise ApiError(502, reason) from None
    found = await asyncio.to_thread(
        trends.trend,
        runtime.recorder,
        MetricKey(group, node, device, metric),
        int(since * 1000),
        end_ms,
        points,
    )
    return [
        TrendPoint(time=p.time_ms / 1000, value=p.value, text=p.text, historical=p.historical)
        for p in found
    ]


_TREND: Final = TypeAdapter(list[TrendPoint])


def _state_name(point: Point) -> str | None:
    if point.text is not None:
        return point.text
    return robot_state_name(int(point.value)) if point.value is not None else None


def _shift(recorder: PlantRecorder, device: MetricKey, start_ms: int, end_ms: int) -> ShiftAnswer:
    """From the history: the robot state (a day before the shift for the state it began in)
    and every ``Cycle/Last`` of the shift."""
    state_key = MetricKey(device.group, device.node, device.device, STATE_METRIC)
    points = recorder.trend(state_key, start_ms - DAY_MS, end_ms)
    before = [p for p in points if p.time_ms <= start_ms][-1:]
    states = [
        (p.time_ms, _state_name(p)) for p in before + [p for p in points if p.time_ms > start_ms]
    ]
    cycle_key = MetricKey(device.group, device.node, device.device, CYCLE_LAST)
    cycles = [p.value for p in recorder.trend(cycle_key, start_ms, end_ms) if p.value is not None]
    figures = shift_figures(states, cycles, start_ms, end_ms)
    return ShiftAnswer(
        seconds=figures.seconds, cycles=figures.cycles, mean_cycle_s=figures.mean_cycle_s
    )


@router.get("/shift", summary="One robot over a shift: time in each state group, cycles")
async def shift(
    request: Request,
    _viewer: ViewerDep,
    *,
    group: str,
    node: str,
    device: str,
    since: Annotated[float, Query(description="the shift's start, epoch s")],
    until: Annotated[float | None, Query(description="its end, epoch s (default: now)")] = None,
) -> ShiftAnswer:
    end_ms = int((until if until is not None else time.time()) * 1000)
    key = MetricKey(group, node, device, STATE_METRIC)
    return await asyncio.to_thread(
        _shift, _runtime(request).recorder, key, int(since * 1000), end_ms
    )


@router.get("/status", summary="The plant's connection and host application counters")
async def status(request: Request, _viewer: ViewerDep) -> StatusAnswer:
    runtime = _runtime(request)
    host = runtime.host
    return StatusAnswer(
        host_id=host.host_id,
        broker=runtime.client.connected_url,
        connections=runtime.client.connections,
        connections_lost=runtime.client.connections_lost,
        subscriptions_refused=runtime.client.subscriptions_refused,
        messages=runtime.messages,
        rebirths=dict(host.rebirths),
        rebirths_held=host.rebirths_held,
        stale_deaths=host.stale_deaths,
        bad_messages=host.bad_messages,
        history_rows=runtime.recorder.rows_written,
    )


class RobotShiftModel(BaseModel):
    group: str
    node: str
    device: str
    seconds: dict[str, float]
    """Seconds in each state group (running, standby, stopped, error) and ``unknown``."""
    cycles: int
    mean_cycle_s: float | None


class ShiftsAnswer(BaseModel):
    since: float
    """The shift's start, epoch s (the last of ``shift_starts`` passed, in ``time_zone``)."""
    until: float
    time_zone: str
    robots: list[RobotShiftModel]


def shift_start(now: datetime, starts: list[str]) -> datetime:
    """The start of the shift in progress at ``now`` (an aware time in the plant's zone):
    the latest of today's (or, before the first, yesterday's) ``HH:MM`` not after it."""
    days = (now.date() - timedelta(days=1), now.date())
    candidates = [
        datetime(d.year, d.month, d.day, int(s[:2]), int(s[3:5]), tzinfo=now.tzinfo)
        for d in days
        for s in starts
    ]
    return max(c for c in candidates if c <= now)


@router.get("/shifts", summary="Every robot over the shift in progress: state groups, cycles")
async def shifts(
    request: Request,
    _viewer: ViewerDep,
    local: Annotated[bool, Query(description="only this process's, not its peers'")] = False,
) -> ShiftsAnswer:
    """What the plant page's shift table shows: ``/shift`` for every device the plant knows,
    over the shift in progress (``shift_starts`` in ``time_zone``, as the kiosk counts); its
    peers' robots as they count them."""
    answer = await _local_shifts(_runtime(request))
    peers = None if local else _peers(request)
    if peers is not None:
        for peer, found in await peers.ask_all("/api/v1/plant/shifts", {}):
            try:
                answer.robots += ShiftsAnswer.model_validate(found).robots
            except ValueError:
                peer.failed("not a shift answer")
    return answer


async def _local_shifts(runtime: PlantRuntime) -> ShiftsAnswer:
    zone_name = runtime.settings.site.time_zone or host_zone_name()
    now = datetime.now(ZoneInfo(zone_name))
    start = shift_start(now, list(runtime.settings.kiosk.shift_starts))
    start_ms, end_ms = int(start.timestamp() * 1000), int(now.timestamp() * 1000)
    keys = [
        MetricKey(group, node, device, STATE_METRIC)
        for (group, node), view in sorted(runtime.host.nodes.items())
        for device in sorted(view.devices)
    ]

    def read() -> list[RobotShiftModel]:
        return [
            RobotShiftModel(
                group=key.group,
                node=key.node,
                device=key.device,
                **_shift(runtime.recorder, key, start_ms, end_ms).model_dump(),
            )
            for key in keys
        ]

    return ShiftsAnswer(
        since=start_ms / 1000,
        until=end_ms / 1000,
        time_zone=zone_name,
        robots=await asyncio.to_thread(read),
    )


class PeerModel(BaseModel):
    url: str
    answering: bool
    since: float
    """Epoch s: since when it answers, or since when it does not."""
    error: str | None
    """Why it does not answer."""
    nodes: int
    """Its edge nodes as it last answered (shown as last answered while it does not)."""


@router.get("/peers", summary="The other plant processes this one's page shows (--peer)")
async def peers(request: Request, _viewer: ViewerDep) -> list[PeerModel]:
    found = _peers(request)
    return [
        PeerModel(
            url=p.url,
            answering=p.answering,
            since=p.since_ms / 1000,
            error=p.error,
            nodes=len(p.nodes),
        )
        for p in (found.peers if found is not None else [])
    ]
