"""What a run shows while flying: the live terminal view implements :class:`View`."""

from __future__ import annotations

from collections.abc import Callable
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


class Views(View):
    """Several views fed the same state (the terminal view and the web map)."""

    def __init__(self, *views: View) -> None:
        self.views = list(views)

    def start(self, state: FleetState, fleet: Fleet | None) -> None:
        for v in self.views:
            v.start(state, fleet)

    async def stop(self) -> None:
        for v in self.views:
            await v.stop()

    def add_status(self, line: Callable[[], str]) -> None:
        """Status lines go to every view that shows them (the terminal view)."""
        for v in self.views:
            add = getattr(v, "add_status", None)
            if add is not None:
                add(line)


__all__ = ["View", "Views"]
