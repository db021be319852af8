"""One way to stay connected to the broker, shared by a run's bus (:class:`fleetctl.bus.client.FleetBus`)
and ``fleetctl watch`` (:class:`fleetctl.views.watch.Watcher`): a connection attempt (TCP, TLS and
CONNACK) takes at most twice ``CONNECT_TIMEOUT``; a failed one is told and retried after a back-off
from ``BACKOFF_MIN`` doubling to ``BACKOFF_MAX``, which a connection that comes up resets."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Callable

import aiomqtt

from fleetctl.bus.config import BACKOFF_MAX, BACKOFF_MIN, CONNECT_TIMEOUT

CLOSE_TIMEOUT = 1.0  # s to wait for a clean DISCONNECT before dropping the client
CONNECTION_ERRORS = (aiomqtt.MqttError, TimeoutError, OSError)  # a broker away, not a bug


class Reconnector:
    """Connects new clients (``make``) until one is up; ``on_failure`` is told each failed attempt."""

    def __init__(self, make: Callable[[], aiomqtt.Client],
                 on_failure: Callable[[BaseException], None]) -> None:
        self.make = make
        self.on_failure = on_failure
        self.delay = BACKOFF_MIN

    async def connect(self) -> aiomqtt.Client:
        """A connected client (retrying with back-off; cancel to give up)."""
        while True:
            client = self.make()
            try:
                async with asyncio.timeout(CONNECT_TIMEOUT * 2):
                    await client.__aenter__()
            except CONNECTION_ERRORS as exc:
                self.on_failure(exc)
                await self.back_off()
                continue
            self.delay = BACKOFF_MIN
            return client

    async def back_off(self) -> None:
        """Wait before the next attempt, each wait twice the last (at most ``BACKOFF_MAX``)."""
        await asyncio.sleep(self.delay)
        self.delay = min(self.delay * 2, BACKOFF_MAX)

    @staticmethod
    async def close(client: aiomqtt.Client) -> None:
        """Disconnect ``client`` (at most ``CLOSE_TIMEOUT``; a broker already gone is no error)."""
        with contextlib.suppress(Exception):
            async with asyncio.timeout(CLOSE_TIMEOUT):
                await client.__aexit__(None, None, None)
