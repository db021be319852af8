"""Waiting for replies on a link: a :class:`Waiter` is a registered expectation (message types from
one system, optionally filtered) that completes a future or fills an :class:`Inbox` - registered
before the request is sent, so that no reply is missed."""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable
from typing import Any

log = logging.getLogger(__name__)


class Waiter:
    """A registered expectation: message types from one system (or any), optionally filtered."""

    __slots__ = ("types", "sysid", "match", "fut", "queue")

    def __init__(self, types: frozenset[str], sysid: int | None, match: Callable[[Any], bool] | None,
                 fut: asyncio.Future[Any] | None, queue: asyncio.Queue[Any] | None) -> None:
        self.types = types
        self.sysid = sysid
        self.match = match
        self.fut = fut
        self.queue = queue

    def offer(self, msg: Any) -> bool:
        """Deliver ``msg`` if it matches; True when this one-shot waiter is done."""
        if self.sysid is not None and msg.get_srcSystem() != self.sysid:
            return False
        if self.match is not None:
            try:
                if not self.match(msg):
                    return False
            except Exception:  # noqa: BLE001 - a faulty matcher must not break the receive path
                log.exception("expectation matcher failed on %s", msg.get_type())
                return False
        if self.queue is not None:
            self.queue.put_nowait(msg)
            return False
        assert self.fut is not None
        if not self.fut.done():
            self.fut.set_result(msg)
        return True


class Inbox:
    """Messages matching an expectation, queued for the duration of one exchange (see
    :meth:`fleetctl.mavlink.link.Link.collect`)."""

    def __init__(self, queue: asyncio.Queue[Any]) -> None:
        self._queue = queue

    async def get(self, timeout: float) -> Any:
        """The next matching message; ``TimeoutError`` after ``timeout`` seconds."""
        async with asyncio.timeout(timeout):
            return await self._queue.get()


__all__ = ["Inbox", "Waiter"]
