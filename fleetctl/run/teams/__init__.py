"""Flying a mission with several carriers (docs/teams.md). Two ways, one module set each:

**Every team in one controller** (``deploy|collect|run`` of a ``carriers:`` mission):

* ``coordinator`` - :class:`TeamsFlight`, what flies in the :class:`~fleetctl.run.crew.Crew` of
  such a mission (one simulated fleet and one set of links for every vehicle): the work shared
  between the teams, one crew of one team per team flown concurrently, hand-over between them,
  the combined records;
* ``team_run`` - :class:`TeamRun`, the flight of one team's crew inside a :class:`TeamsFlight`
  (a :class:`~fleetctl.run.runner.TeamFlight` with further deployment rounds for handed-over
  tasks, mission-clock times), :func:`team_crew` making that crew, and :func:`fly_team` to fly
  one team's share alone;
* ``board`` (who owns what, each team's state), ``handover`` (re-sharing tasks a team cannot
  fly), ``live`` (the carriers' live poses, the rovers in the field), ``summary``, ``views``,
  ``bus`` (the MQTT buses: each team under ``P/teams/<carrier>`` as a ``--team`` controller
  publishes, the run under ``P``).

**One controller per team** (``deploy|run --team ID``, coordinating over MQTT, docs/mqtt.md#teams):

* ``own_controller`` - :class:`~fleetctl.run.teams.own_controller.TeamControllerRun`, the run
  of this controller's team, and how its share and bus are set up (``prepare_team``,
  ``team_bus_config``, ``fly_team_controller``);
* ``link`` - :class:`~fleetctl.run.teams.link.TeamLink`, the asyncio side of the coordination
  with the other teams' controllers (presence, claims, hand-over); the protocol and its rules are
  in :mod:`fleetctl.bus.teams`.

Both fly a team's further deployment rounds with the one rounds loop of
:class:`~fleetctl.run.runner.TeamFlight` (:mod:`fleetctl.run.rounds`); ``rounds`` holds where each gets
them from (``CoordinatorWork``: the run of every team; ``LinkWork``: the link).

Only the one-controller names are imported here; import the ``--team`` modules directly.
"""

from fleetctl.run.teams.board import Handover, TeamEntry, TeamsBoard, TeamStatus
from fleetctl.run.teams.coordinator import TeamsFlight
from fleetctl.run.teams.team_run import TeamRun, fly_team

__all__ = ["Handover", "TeamEntry", "TeamRun", "TeamStatus", "TeamsBoard", "TeamsFlight", "fly_team"]
