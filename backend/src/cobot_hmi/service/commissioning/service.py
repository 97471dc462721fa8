"""Layer: service. The commissioning tools of every robot of the service: each robot's checkouts
(``CheckoutBook``), the frame watcher that marks their inputs seen (``CheckoutWatcher``) and
its presets (``PresetBook``). Started after the service (its store open, its robots started):
the open checkouts are read back from the database and watched again, so a checkout goes on
after a restart."""

from __future__ import annotations

from cobot_hmi.service.commissioning.checkout import CheckoutBook
from cobot_hmi.service.commissioning.presets import PresetBook
from cobot_hmi.service.commissioning.watcher import CheckoutWatcher
from cobot_hmi.service.runtime import Service


class Commissioning:
    def __init__(self, service: Service) -> None:
        self.checkouts = {name: CheckoutBook(name, service.store) for name in service.robots}
        self.watchers = {
            name: CheckoutWatcher(self.checkouts[name], robot.frames)
            for name, robot in service.robots.items()
        }
        self.presets = {name: PresetBook(name, service.store) for name in service.robots}

    async def start(self) -> None:
        for name, book in self.checkouts.items():
            await book.load()
            self.watchers[name].update()

    async def stop(self) -> None:
        for watcher in self.watchers.values():
            await watcher.stop()
