"""What a run shows while flying: the live terminal view implements :class:`View`."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from fleetctl.mavlink.fleet import Fleet
    from fleetctl.run.state import FleetState


class View:
    """The interface the runner drives (:mod:`fleetctl.views.dashboard` implements it)."""

    def start(self, state: FleetState, fleet: Fleet | None) -> None:  # pragma: no cover - interface
        pass

    async def stop(self) -> None:  # pragma: no cover - interface
        pass


__all__ = ["View"]
