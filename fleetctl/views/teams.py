"""The teams a view shows: one :class:`~fleetctl.run.state.FleetState` per team, in a fixed order
with a colour each (:data:`TEAM_COLOURS`), for the terminal view and the web map.

A one-team run, ``replay`` and a one-team ``watch`` give a view one state (``View.start``): it is
shown as it always was, without a team heading or colour. A run of several teams gives each
team's state (``View.start_team``, again for each phase: the latest state of a team is the one
shown); ``watch`` gives the state of the run (its events) and one state per team it hears of.

Order and colours: teams are numbered in the order :meth:`ShownTeams.declare` names them (the
mission's ``carriers:``), then in the order they first appear; team *k* has colour *k* of
:data:`TEAM_COLOURS` (cycling), for the whole run. A vehicle shown by two teams (a rover a
collection lands on the other carrier, still in the finished deployment of its own team) is
shown with the team whose state came last.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from fleetctl.run.state import Event, FleetState, VehicleState

# distinct on the map's dark background and in a terminal; none is a rover state's colour there
TEAM_COLOURS = ("#ff8c42", "#4fc3f7", "#c77dff", "#9be564", "#ff6f91", "#ffd166", "#2ec4b6", "#bc8a5f")
MAX_TEAMS = 32  # teams a view keeps (watch: outside input is bounded)


@dataclass(frozen=True)
class ShownTeam:
    """One team as a view shows it; ``team`` and ``colour`` are None for a one-team view."""

    team: str | None
    state: FleetState
    colour: str | None


class ShownTeams:
    """The states a view draws (see the module docstring)."""

    def __init__(self) -> None:
        self.main: FleetState | None = None  # View.start: the one state, or (watch) the run's
        self.order: list[str] = []
        self.states: dict[str, FleetState] = {}
        self._set_at: dict[str, int] = {}  # team -> when its state was last set (a counter)
        self._sets = 0

    def declare(self, teams: Iterable[str], *, every: bool = False) -> None:
        """The teams' order (colours follow it): known teams keep their place, unless ``every``
        (the complete list, e.g. a run's status on the bus: it also orders the teams already known)."""
        teams = list(teams)
        if every:
            self.order = list(dict.fromkeys(teams)) + [t for t in self.order if t not in teams]
            del self.order[MAX_TEAMS:]
        for t in teams:
            if t not in self.order and len(self.order) < MAX_TEAMS:
                self.order.append(t)

    def set_main(self, state: FleetState) -> None:
        self.main = state

    def set_team(self, team: str, state: FleetState) -> bool:
        """``team``'s state from now on; False (ignored) beyond :data:`MAX_TEAMS` teams."""
        self.declare([team])
        if team not in self.order:
            return False
        self._sets += 1
        self.states[team] = state
        self._set_at[team] = self._sets
        return True

    @property
    def several(self) -> bool:
        """Teams are shown (with headings and colours), rather than one state."""
        return bool(self.states)

    def colour(self, team: str) -> str:
        return TEAM_COLOURS[self.order.index(team) % len(TEAM_COLOURS)]

    def shown(self) -> list[ShownTeam]:
        """What to draw: every team in order, else the one state (nothing before a state came)."""
        if self.states:
            return [ShownTeam(t, self.states[t], self.colour(t)) for t in self.order if t in self.states]
        return [ShownTeam(None, self.main, None)] if self.main is not None else []

    def vehicles(self) -> list[tuple[ShownTeam, VehicleState]]:
        """Every vehicle once, with the team that shows it (teams in order, each carrier first)."""
        teams = self.shown()
        owner: dict[str, ShownTeam] = {}
        for st in sorted(teams, key=lambda s: self._set_at.get(s.team or "", 0)):
            for vid in st.state.vehicles:
                owner[vid] = st  # the team whose state came last wins
        return [(st, v) for st in teams for vid, v in st.state.vehicles.items() if owner[vid] is st]

    def events(self, count: int) -> list[tuple[ShownTeam | None, Event]]:
        """The latest ``count`` events of every team (and of the run, from watch) in mission-time
        order; the team is None for the run's own events."""
        out: list[tuple[ShownTeam | None, Event]] = []
        for st in self.shown():
            out += [(st if st.team is not None else None, ev) for ev in list(st.state.events)]
        if self.states and self.main is not None:
            out += [(None, ev) for ev in list(self.main.events)]
        out.sort(key=lambda x: x[1].mission_time if x[1].mission_time is not None else 0.0)
        return out[-count:] if count > 0 else []

    @property
    def mission_name(self) -> str:
        """The one state's mission name (watch: the controller's once it said it), else the first team's."""
        shown = self.shown()
        if self.main is not None and (not self.states or self.main.mission_name != "?"):
            return self.main.mission_name
        return shown[0].state.mission_name if shown else "?"

    @property
    def mission_time(self) -> float | None:
        """T+ now: the latest of the teams' (one clock: every team counts from the run's start)."""
        times = [st.state.mission_time for st in self.shown()]
        if self.main is not None and self.states:
            times.append(self.main.mission_time)
        return max(times) if times else None


__all__ = ["MAX_TEAMS", "TEAM_COLOURS", "ShownTeam", "ShownTeams"]
