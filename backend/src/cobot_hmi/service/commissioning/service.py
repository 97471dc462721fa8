"""Layer: service. The commissioning tools of every robot of the service: each robot's checkouts
(``CheckoutBook``) and the frame watcher that marks their inputs seen (``CheckoutWatcher``). The
service (``runtime``) makes it and starts it with itself, once its store is open and before the
first frame: the open checkouts are read back from the database and watched again, so a
checkout goes on after a restart. (A robot's presets need no state of their own: each request
reads them from the store, ``presets.PresetBook``.)"""

from __future__ import annotations

from collections.abc import Mapping

from cobot_hmi.service.commissioning.checkout import CheckoutBook
from cobot_hmi.service.commissioning.watcher import CheckoutWatcher
from cobot_hmi.service.robots.robot import RobotRuntime
from cobot_hmi.service.storage.store import Store


class Commissioning:
    def __init__(self, robots: Mapping[str, RobotRuntime], store: Store) -> None:
        self.checkouts = {name: CheckoutBook(name, store) for name in robots}
        self.watchers = {
            name: CheckoutWatcher(self.checkouts[name], robot.frames)
            for name, robot in robots.items()
        }

    async def start(self) -> None:
        for name, book in self.checkouts.items():
            await book.load()
            self.watchers[name].update()

    async def stop(self) -> None:
        for watcher in self.watchers.values():
            await watcher.stop()
