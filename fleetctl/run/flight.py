"""What the command line calls to fly: :func:`fly` (:func:`execute` takes the options as keywords).

Every mission flies through one :class:`~fleetctl.run.crew.Crew` (the lifecycle, once); what flies
in it is chosen by the mission's data: one team is a :class:`~fleetctl.run.runner.TeamFlight`,
several teams a :class:`~fleetctl.run.teams.coordinator.TeamsFlight`, which flies each team as a
crew of one team on its share (docs/teams.md).
"""

from __future__ import annotations

from typing import Any

from fleetctl.mission import Mission
from fleetctl.mission.teams import mission_teams
from fleetctl.run.crew import Crew
from fleetctl.run.lifecycle import COMMANDS, RunOptions, RunOutcome
from fleetctl.run.runner import TeamFlight
from fleetctl.run.teams.coordinator import TeamsFlight


async def fly(mission: Mission, command: str, opts: RunOptions) -> RunOutcome:
    """Fly ``command`` (``deploy`` | ``collect`` | ``run``) of ``mission`` end to end: start the
    embedded simulator for ``connection: sim``, connect, fly, and write the records.

    Options (:class:`~fleetctl.run.lifecycle.RunOptions`): ``sim`` - an already running
    ``sitl.SimFleet`` to fly against (tests, benchmarks); ``on_sim`` - called with the embedded
    simulator once it runs; ``clock_speedup`` - vehicles that run that much faster than the wall
    clock elsewhere (mission time = wall x it); ``mqtt`` - a :class:`fleetctl.bus.config.BusConfig`
    (default: the mission's ``mqtt:`` section); ``run_dir`` - the records folder; ``on_run_dir`` -
    told it first; ``resume`` - a :class:`~fleetctl.run.resume.Resumption` to finish."""
    if command not in COMMANDS:
        raise ValueError(f"unknown command {command!r}")
    flight: type[TeamFlight | TeamsFlight] = TeamsFlight if len(mission_teams(mission)) > 1 else TeamFlight
    return await Crew(mission, command, opts, flight).fly()


async def execute(mission: Mission, command: str, **options: Any) -> RunOutcome:
    """:func:`fly` with the :class:`~fleetctl.run.lifecycle.RunOptions` given as keywords (tests,
    benchmarks)."""
    return await fly(mission, command, RunOptions(**options))


__all__ = ["execute", "fly"]
