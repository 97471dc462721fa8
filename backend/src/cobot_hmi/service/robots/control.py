"""Layer: service. Who holds control of the robot's outputs: one session at a time.

Taking control switches the O→T run/idle header to run with an image seeded from the robot's
own actual outputs (its last frame), so the takeover changes nothing on the robot until
someone writes (bumpless). Releasing goes back to idle. Control ends with the holder's logout,
session expiry, last WebSocket, or the connection's loss (a reconnected originator starts idle,
so keeping a holder would claim a run that is not happening).

Taking and releasing control on request are audited as a write is: a ``pending`` row before
anything changes (an ``AuditUnavailableError``, 503, when the audit trail cannot be written:
nothing changes), its outcome after. Control that ends without a request (logout, expiry,
connection loss) and refusals are audited after the fact; on a full disk their rows wait in
memory until there is room (``store.keep_audit``).
"""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections.abc import Callable
from dataclasses import dataclass

from cobot_hmi.layout import FRAME_ECHOED
from cobot_hmi.scanner.originator import ConnectionState, NotConnectedError, ReadOnlyError
from cobot_hmi.service.access.auth import Session
from cobot_hmi.service.access.users import Role
from cobot_hmi.service.errors import AuditUnavailableError, conflict
from cobot_hmi.service.events.text import Event
from cobot_hmi.service.robots.frame_notifier import FrameNotifier
from cobot_hmi.service.robots.link import RobotLink
from cobot_hmi.service.storage.store import AuditEntry, Store


@dataclass(frozen=True, slots=True)
class Holder:
    session_id: str
    user: str
    since: float
    client: str | None

    def to_json(self) -> dict[str, object]:
        return {"user": self.user, "since": self.since, "session": self.session_id}

    def describe_for(self, session: Session | None) -> str:
        """Who holds control, as the refusal to ``session`` says it: a user, or the same user
        in another session (another window: control belongs to a session)."""
        if session is not None and session.user.name == self.user:
            return f"you ({self.user}) in another session (another window or device)"
        return self.user


class Control:
    """The control token and its changes (audited, announced as ``control`` events)."""

    def __init__(
        self,
        link: RobotLink,
        store: Store,
        frames: FrameNotifier,
        publish_event: Callable[[Event], None],
        *,
        input_only: bool,
    ) -> None:
        self._link = link
        self._store = store
        self._frames = frames
        self._publish_event = publish_event
        self._input_only = input_only
        self.holder: Holder | None = None
        self.lock = asyncio.Lock()
        """Held by take, release and every write: they never interleave."""

    def status(self) -> dict[str, object]:
        return {"holder": None if self.holder is None else self.holder.to_json()}

    def status_for(self, session: Session | None) -> dict[str, object]:
        """``status()`` as one requester sees it: ``holder.session_is_yours`` says whether
        ``session`` holds control (null without a session)."""
        holder = self.holder
        if holder is None:
            return {"holder": None}
        mine = None if session is None else holder.session_id == session.id
        return {"holder": {**holder.to_json(), "session_is_yours": mine}}

    def holds(self, session: Session) -> bool:
        return self.holder is not None and self.holder.session_id == session.id

    def refusal_to_write(self) -> str | None:
        """Why nobody could write now (connection or mode), or ``None``."""
        if self._input_only:
            return "read-only mode: the service holds an input-only connection"
        state = self._link.state
        if state is not ConnectionState.CONNECTED:
            reason = self._link.reason
            return f"not connected to the robot ({state.value}{': ' + reason if reason else ''})"
        return None

    async def take(self, session: Session, client: str | None) -> dict[str, object]:
        user = session.user.name
        async with self.lock:
            holder = self.holder
            if holder is not None and holder.session_id != session.id:
                await self._audit(user, client, "control.take", "refused", "held")
                raise conflict(f"control is held by {holder.describe_for(session)}")
            refusal = self.refusal_to_write()
            if refusal is not None:
                await self._audit(user, client, "control.take", "refused", refusal)
                raise conflict(refusal)
            if holder is None:
                row_id = await self._pending(user, client, "control.take", "control was not taken")
                refusal = await self._go_run()
                if refusal is not None:
                    await self._store.finish_audit(row_id, "refused", refusal)
                    raise conflict(refusal)
                self.holder = Holder(session.id, user, time.time(), client)
                await self._store.finish_audit(row_id, "granted", None)
                self._announce("taken")
            return self.status()

    async def _go_run(self) -> str | None:
        """Seed the image from the robot's actual outputs, then run. A refusal, or ``None``."""
        latest = self._frames.latest
        image = self._link.command
        if latest is not None:
            frame = latest.frame
            image = image._replace(**{name: getattr(frame, name) for name in FRAME_ECHOED})
        try:
            await self._link.set_command(image)
            await self._link.set_run(True)
        except ReadOnlyError:
            return "read-only mode: the service holds an input-only connection"
        except NotConnectedError as error:
            return f"not connected to the robot ({error})"
        return None

    async def release(self, session: Session, client: str | None) -> dict[str, object]:
        """The holder (or an admin) gives control back; O→T goes idle."""
        async with self.lock:
            holder = self.holder
            if holder is None:
                return self.status()
            if holder.session_id != session.id and session.user.role < Role.ADMIN:
                await self._audit(session.user.name, client, "control.release", "refused", "held")
                raise conflict(
                    f"control is held by {holder.describe_for(session)}; only the session "
                    "holding it (or an admin) may release it"
                )
            reason = "released" if holder.session_id == session.id else "released by an admin"
            user = session.user.name
            row_id = await self._pending(
                user, client, "control.release", "control was not released"
            )
            await self._end(user, client, reason, row_id=row_id)
            return self.status()

    async def drop(self, reason: str, *, session_id: str | None = None) -> None:
        """End control without a request: logout, expiry, disconnect, connection loss.

        With ``session_id`` only that session's control ends.
        """
        async with self.lock:
            holder = self.holder
            if holder is None or (session_id is not None and holder.session_id != session_id):
                return
            await self._end(holder.user, holder.client, reason)

    async def _end(
        self, user: str, client: str | None, reason: str, *, row_id: int | None = None
    ) -> None:
        """Idle, no holder, audited (the ``pending`` row ``row_id`` of a request's, or a row
        of its own), announced."""
        # Idle first, then let go: nobody may see "no one holds control" while O→T still runs.
        with contextlib.suppress(NotConnectedError, ReadOnlyError):
            await self._link.set_run(False)  # without a connection nothing runs anyway
        self.holder = None
        if row_id is None:
            await self._audit(user, client, "control.release", "released", reason, happened=True)
        else:
            await self._store.finish_audit(row_id, "released", reason)
        self._announce(reason)

    def _announce(self, reason: str) -> None:
        self._publish_event(
            {"kind": "control", "time": time.time(), **self.status(), "reason": reason}
        )

    def _entry(
        self, user: str, client: str | None, action: str, outcome: str, reason: str | None
    ) -> AuditEntry:
        return AuditEntry(
            user=user,
            client=client,
            action=action,
            fields=[],
            before=None,
            requested=None,
            outcome=outcome,
            reason=reason,
            robot=self._link.name,
        )

    async def _audit(
        self,
        user: str,
        client: str | None,
        action: str,
        outcome: str,
        reason: str | None,
        *,
        happened: bool = False,
    ) -> None:
        """A row after the fact (kept in memory while the disk is full)."""
        await self._store.keep_audit(
            self._entry(user, client, action, outcome, reason), happened=happened
        )

    async def _pending(self, user: str, client: str | None, action: str, not_done: str) -> int:
        """The ``pending`` row of a request, before anything changes; a 503 refusal
        (``AuditUnavailableError``) saying ``not_done`` when it cannot be written (its own row
        kept until there is room)."""
        try:
            return await self._store.add_audit(
                self._entry(user, client, action, "pending", None), fsync=False
            )
        except AuditUnavailableError as error:
            refusal = error.refusing(not_done)
            await self._audit(user, client, action, "refused", refusal.reason)
            raise refusal from None
