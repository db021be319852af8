"""What a run shows while flying: the live terminal view and the web map implement :class:`View`.

A view is given the state it draws: one :class:`FleetState` (``start``), or, in a run of several
teams, each team's (``start_team``, with ``declare_teams`` naming the teams in order first).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from fleetctl.mavlink.fleet import Fleet
    from fleetctl.run.state import FleetState


class View:
    """The interface the runner drives (:mod:`fleetctl.views.dashboard` implements it)."""

    _first_team: str | None = None  # the team a view of one state shows (start_team's default)

    def start(self, state: FleetState, fleet: Fleet | None) -> None:  # pragma: no cover - interface
        pass

    async def stop(self) -> None:  # pragma: no cover - interface
        pass

    def declare_teams(self, teams: Sequence[str], *, every: bool = False) -> None:
        """The teams of a run of several, in the order they are shown (the mission's carriers);
        ``every``: the complete list, which also orders the teams already known."""

    def start_team(self, team: str, state: FleetState, fleet: Fleet | None) -> None:
        """``team``'s state (a run of several teams: each team's run calls this as it starts a
        phase). A view that shows every team draws it beside the others; this default, for a view
        of one state, shows the first team it is given."""
        if self._first_team is None:
            self._first_team = team
        if team == self._first_team:
            self.start(state, fleet)


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

    def declare_teams(self, teams: Sequence[str], *, every: bool = False) -> None:
        for v in self.views:
            v.declare_teams(teams, every=every)

    def start_team(self, team: str, state: FleetState, fleet: Fleet | None) -> None:
        for v in self.views:
            v.start_team(team, state, fleet)

    def add_status(self, line: Callable[[], str]) -> None:
        """Status lines go to every view that shows them (the terminal view)."""
        for v in self.views:
            add = getattr(v, "add_status", None)
            if add is not None:
                add(line)


__all__ = ["View", "Views"]
