"""One way to stay connected to the broker, shared by a run's bus (:class:`fleetctl.bus.client.FleetBus`)
and ``fleetctl watch`` (:class:`fleetctl.views.watch.Watcher`): a connection attempt (TCP, TLS and
CONNACK) takes at most twice ``CONNECT_TIMEOUT``; a failed one is told and retried after a back-off
from ``BACKOFF_MIN`` doubling to ``BACKOFF_MAX``, which a connection that comes up resets."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Callable

import aiomqtt

from fleetctl.bus.config import BACKOFF_MAX, BACKOFF_MIN, CONNECT_TIMEOUT, BusStatus

MAX_ERROR_TEXT = 300  # characters of the last error kept for the status line and the summary
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


class ConnectionStatus:
    """Where a client's connection stands (:class:`BusStatus`) and why its last attempt failed or
    its connection dropped; :meth:`change_status` is the one setter of both."""

    status: BusStatus = BusStatus.CONNECTING
    last_error: str | None = None

    def change_status(self, status: BusStatus, error: BaseException | None = None) -> BusStatus | None:
        """Record ``error`` and move to ``status``: the status before when it changed, else None."""
        if error is not None:
            self.last_error = (str(error) or type(error).__name__)[:MAX_ERROR_TEXT]
        if status == self.status:
            return None
        old, self.status = self.status, status
        return old
