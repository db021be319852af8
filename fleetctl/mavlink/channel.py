"""What the MAVLink protocols need of a link: a :class:`Channel`.

The command and mission protocols (:mod:`fleetctl.mavlink.command_protocol`,
:mod:`fleetctl.mavlink.mission_protocol`) run their exchanges over this interface, not over
:class:`fleetctl.mavlink.link.Link` itself: the link implements it (and calls the protocols), so
the protocols do not import the link and the two modules do not import each other. A test can
run a protocol over any object with these members.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable, Iterable
from contextlib import AbstractContextManager
from typing import Any, Protocol

from fleetctl.mavlink.expectations import Inbox
from fleetctl.mavlink.rtt import RoundTrip


class Channel(Protocol):
    """A MAVLink connection as the protocols use it."""

    url: str  # for messages and logs
    mav: Any  # the pymavlink encoder (``mav.<message>_encode``) of this side
    rtt: RoundTrip  # the commands' round trips: how long an attempt waits before a resend
    mission_rtt: float  # s, the last mission exchange's round trip (sets a download's item timeout)

    def send(self, msg: Any, sysid: int | None = None) -> None:
        """Send ``msg`` to system ``sysid`` (None: broadcast)."""
        ...

    def collect(self, types: str | Iterable[str], *, sysid: int | None = None,
                match: Callable[[Any], bool] | None = None) -> AbstractContextManager[Inbox]:
        """Queue every matching message while the ``with`` block runs (registered before a request)."""
        ...

    def lock(self, key: Any) -> asyncio.Lock:
        """One exchange of a kind at a time (``key``: e.g. a command and a vehicle)."""
        ...


__all__ = ["Channel"]
