"""Flying a mission with several carriers (docs/teams.md): every team at once in one controller
(:class:`TeamsRun`), or one team alone (:func:`fly_team`)."""

from fleetctl.run.teams.board import Handover, TeamEntry, TeamsBoard, TeamStatus
from fleetctl.run.teams.coordinator import TeamsRun
from fleetctl.run.teams.team_run import TeamRun, fly_team

__all__ = ["Handover", "TeamEntry", "TeamRun", "TeamStatus", "TeamsBoard", "TeamsRun", "fly_team"]
