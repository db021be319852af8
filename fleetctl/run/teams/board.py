"""The teams board of a several-carrier run: where every team and every task stands.

Each team (a carrier and its rovers) is *waiting* (connected, not flying yet), *deploying*,
*settling* (its deployment round is over; it may still be handed tasks), *collecting*, *done*
or *failed* (its run ended with an error). A team whose carrier's link was down too long is
``lost``: it hands its unlaunched tasks over and is handed none. Every task has one owner team
at a time; a hand-over moves it and is recorded. Nothing here touches the fleet: the coordinator
(:mod:`fleetctl.run.teams.coordinator`) changes the board.
"""

from __future__ import annotations

import asyncio
from dataclasses import dataclass, field
from enum import StrEnum

from planners.core.problem import Task


class TeamStatus(StrEnum):
    WAITING = "waiting"
    DEPLOYING = "deploying"
    SETTLING = "settling"
    COLLECTING = "collecting"
    DONE = "done"
    FAILED = "failed"


ACTIVE = (TeamStatus.WAITING, TeamStatus.DEPLOYING)  # may still reach tasks or hand some over
CAN_RECEIVE = (TeamStatus.DEPLOYING, TeamStatus.SETTLING)  # may be handed tasks


@dataclass
class Handover:
    tasks: list[str]
    from_team: str
    to_team: str | None  # None: no team could take them
    why: str
    t: float  # mission clock


@dataclass
class TeamEntry:
    carrier: str
    rovers: tuple[str, ...]  # its deck
    tasks: list[str] = field(default_factory=list)  # allocated by the teams plan
    status: TeamStatus = TeamStatus.WAITING
    received: list[Task] = field(default_factory=list)  # handed to it, in order
    lost_since: float | None = None  # mission clock: its carrier's link went down
    lost: bool = False  # its carrier was lost for too long: it takes no more tasks
    finished: bool = False  # its deployment is over (no further round)

    @property
    def can_receive(self) -> bool:
        return self.status in CAN_RECEIVE and not self.lost and not self.finished


@dataclass
class TeamsBoard:
    teams: dict[str, TeamEntry] = field(default_factory=dict)  # in the mission's order
    owner: dict[str, str] = field(default_factory=dict)  # task -> the team that owns it now
    reached: dict[str, tuple[str, float]] = field(default_factory=dict)  # task -> (team, mission clock)
    handovers: list[Handover] = field(default_factory=list)
    gave_up: dict[str, set[str]] = field(default_factory=dict)  # task -> teams that handed it over
    changed: asyncio.Event = field(default_factory=asyncio.Event)  # set on every change

    def allocate(self, team: str, tasks: list[str]) -> None:
        self.teams[team].tasks = list(tasks)
        for tid in tasks:
            self.owner[tid] = team

    def set_status(self, team: str, status: TeamStatus) -> None:
        self.teams[team].status = status
        self.touch()

    def touch(self) -> None:
        self.changed.set()

    def owned_unreached(self, team: str) -> list[str]:
        return [t for t, o in self.owner.items() if o == team and t not in self.reached]

    def hand_over(self, tasks: list[Task], from_team: str, to_team: str, why: str, t: float) -> Handover:
        for task in tasks:
            self.owner[task.id] = to_team
            self.gave_up.setdefault(task.id, set()).add(from_team)
        receiver = self.teams[to_team]
        receiver.received.extend(tasks)
        if receiver.status == TeamStatus.SETTLING:  # it flies them in a further round
            receiver.status = TeamStatus.DEPLOYING
        h = Handover([task.id for task in tasks], from_team, to_team, why, t)
        self.handovers.append(h)
        self.touch()
        return h

    def settled(self) -> bool:
        """Every team whose carrier is not lost is past deploying (a lost one is not waited for)."""
        return not any(e.status in ACTIVE and not e.lost for e in self.teams.values())

    def unserved(self) -> list[str]:
        return [t for t in self.owner if t not in self.reached]


__all__ = ["ACTIVE", "CAN_RECEIVE", "Handover", "TeamEntry", "TeamStatus", "TeamsBoard"]
