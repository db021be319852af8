"""What each team's run shows: headless, every team's events on the one output, each line
prefixed with its carrier; the live terminal view and the web map show every team, each team's
run handing its state to them (``View.start_team``). They are stopped by the run of every team,
not by the teams' runs."""

from __future__ import annotations

from typing import TYPE_CHECKING

from fleetctl.views.dashboard import HeadlessView
from fleetctl.views.view import View, Views

if TYPE_CHECKING:
    from fleetctl.mavlink.fleet import Fleet
    from fleetctl.run.state import FleetState


class SharedView(View):
    """A team's port to the run's view: its state is shown as ``team``'s; stopping is left to the
    run of every team."""

    def __init__(self, view: View, team: str) -> None:
        self.view = view
        self.team = team

    def start(self, state: FleetState, fleet: Fleet | None) -> None:
        self.view.start_team(self.team, state, fleet)

    async def stop(self) -> None:
        return None


def team_views(view: View | None, teams: list[str]) -> dict[str, View | None]:
    if view is None:
        return dict.fromkeys(teams)
    view.declare_teams(teams)
    if isinstance(view, HeadlessView):
        width = max(len(t) for t in teams)
        return {t: HeadlessView(view.out, prefix=f"{t:<{width}} ") for t in teams}
    if isinstance(view, Views) and any(isinstance(v, HeadlessView) for v in view.views):
        heads = [v for v in view.views if isinstance(v, HeadlessView)]
        others = [v for v in view.views if not isinstance(v, HeadlessView)]
        width = max(len(t) for t in teams)
        return {
            t: Views(
                HeadlessView(heads[0].out, prefix=f"{t:<{width}} "), *(SharedView(v, t) for v in others)
            )
            for t in teams
        }
    return {t: SharedView(view, t) for t in teams}


__all__ = ["SharedView", "team_views"]
