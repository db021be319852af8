"""The MQTT fleet bus of a run of several teams in one controller (docs/mqtt.md#teams-in-one-controller).

With a bus (``--mqtt URL`` or the mission's ``mqtt:`` section) :class:`TeamsBuses` owns one
:class:`~fleetctl.bus.client.FleetBus` for the whole run (prefix ``P``: the combined status and the
run's own journal on ``P/events``) and one per team, from the first sharing of the work to the
end: prefix ``P/teams/<carrier>`` (:func:`~fleetctl.run.teams.own_controller.team_bus_config`,
as a ``--team`` controller publishes), with that team's identity in its status and last will.
Each phase's run of a team publishes on its team's bus (``RunOptions.bus``: status, plan,
telemetry, events); between two phases (a ``run``'s dwell) the team's telemetry pauses. No
claims or progress are published: the coordinator owns the allocation. Task messages are
refused (answered on ``.../errors``). Flying never waits on the broker.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import uuid
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from fleetctl.bus.client import FleetBus
from fleetctl.bus.config import STATUS_EVENT, BusConfig, BusConfigError, BusStatus, bus_config
from fleetctl.bus.teams.protocol import allocation_hash
from fleetctl.mission import Mission
from fleetctl.run.kinds import Ev
from fleetctl.run.teams.own_controller import team_bus_config

log = logging.getLogger(__name__)

REFUSED = ("task changes over MQTT are not supported yet in a run of several teams in one controller; "
           "nothing changed")
ONE_CONTROLLER = "(every team in one controller)"  # in the allocation hash
CLOSE_TIMEOUT = 3.0  # s each bus may take to flush its last messages on the way out


class TeamsBuses:
    """The buses of one run of several teams (see the module docstring)."""

    def __init__(self, mission: Mission, config: BusConfig | None, record: Callable[..., None],
                 vehicles: str) -> None:
        self.mission, self.config, self.record, self.vehicles = mission, config, record, vehicles
        self.top: FleetBus | None = None
        self.teams: dict[str, FleetBus] = {}

    @classmethod
    def configure(cls, mission: Mission, config: BusConfig | None, record: Callable[..., None],
                  vehicles: str) -> TeamsBuses:
        """``config`` (``--mqtt``), else the mission's ``mqtt:`` section; a bad setting is journaled
        and the run flies without a bus."""
        if config is None:
            try:
                config = bus_config(mission)
            except BusConfigError as exc:
                record(Ev.BUS, text=f"bus: off ({exc})")
                config = None
        return cls(mission, config, record, vehicles)

    def start(self, teams: Sequence[str]) -> None:
        """The run's own bus under ``P`` (needs a running loop); every journal record of the run
        goes out on ``P/events`` through :meth:`on_record`."""
        if self.config is None:
            return
        bus = self.top = FleetBus(self.config, self.mission)
        bus.identity = {"teams": list(teams)}
        bus.refuse_tasks = REFUSED
        bus.add_status_listener(self._on_connection)
        bus.start(None, self.record)
        self.record(Ev.BUS, url=self.config.url, topic_prefix=self.config.topic_prefix,
                    username=self.config.username, tls=self.config.tls,
                    teams={k: f"{self.config.topic_prefix}/teams/{k}" for k in teams})

    def on_record(self, rec: dict[str, Any]) -> None:
        if self.top is not None:
            self.top.on_record(rec)

    def _on_connection(self, status: BusStatus) -> None:
        told = (BusStatus.CONNECTED, BusStatus.RECONNECTING, BusStatus.FAILED)
        if self.config is not None and status in told:
            error = self.top.last_error if self.top is not None and status != BusStatus.CONNECTED else None
            text = f"bus: {status} {self.config.url}" + (f" ({error})" if error else "")
            if status == BusStatus.RECONNECTING:
                text += "; messages are queued (the mission flies on)"
            self.record(STATUS_EVENT[status], text=text, error=error)

    def start_teams(self, shares: Mapping[str, Sequence[str]]) -> None:
        """Every team's bus (first call only): ``shares`` (team -> its tasks or rovers) gives the
        allocation hash of their statuses."""
        if self.config is None or self.teams:
            return
        # never a --team controller's hash (which a peer would take for its own allocation: this
        # run publishes no progress or claims, so it must be ignored, not coordinated with)
        alloc = allocation_hash(f"{self.mission.name} {ONE_CONTROLLER}", shares)
        for team in shares:
            config = team_bus_config(self.config, team)
            assert config is not None
            bus = FleetBus(config, self.mission)
            bus.identity = {"team": team, "session": uuid.uuid4().hex[:12], "allocation": alloc,
                            "vehicles": self.vehicles}
            bus.refuse_tasks = REFUSED
            bus.start(None, self.record)
            self.teams[team] = bus

    def of(self, team: str) -> FleetBus | None:
        return self.teams.get(team)

    def stats(self) -> dict[str, Any] | None:
        """The summary's ``mqtt`` section: the run's bus, and each team's under ``teams``."""
        if self.top is None:
            return None
        return self.top.stats() | {"teams": {k: b.stats() for k, b in self.teams.items()}}

    async def aclose(self, final: str, team_final: Mapping[str, str]) -> None:
        """Every team's final status, then the run's, each flushed if connected; every bus task ends."""
        buses = [(b, team_final.get(k, final)) for k, b in self.teams.items()]
        if self.top is not None:
            buses.append((self.top, final))

        async def close(bus: FleetBus, status: str) -> None:
            with contextlib.suppress(Exception):
                await bus.aclose(status, flush_timeout=CLOSE_TIMEOUT)

        if buses:
            await asyncio.gather(*(close(b, s) for b, s in buses))
        self.teams.clear()
        self.top = None


__all__ = ["TeamsBuses"]
