"""Cross-team replanning: tasks a team cannot serve go to the teams that still can.

The receiving teams are chosen by the time model: the handed tasks are shared out again with
``planners.teams`` over every team that may take tasks (deploying or settling, its carrier not
lost), each from its carrier's live pose with the rovers it has left on its deck (those not
needed by its own pooled tasks; a team still starting - connecting, preflight - from its start
with the rovers of its roster its share leaves over). A team still deploying gets its share as a task change
(:meth:`~fleetctl.run.executor.Executor.submit_task_change`, source ``team <from>``); a team
that finished deploying flies it in a further round (:meth:`TeamsFlight.more_work`). Tasks no team
can take stay unserved, owned by the team that gave them up. Every hand-over is journalled
(``handover``: tasks, from, to, why).
"""

from __future__ import annotations

import asyncio
import dataclasses
from typing import TYPE_CHECKING

from fleetctl.run.kinds import Ev
from fleetctl.run.launch import rover_on_deck
from fleetctl.run.task_board import TaskStatus
from fleetctl.run.teams.board import Handover, TeamStatus
from fleetctl.run.teams.team_run import TeamRun
from fleetctl.teams_plan import share_teams
from planners.core.problem import Task
from planners.teams import TeamsProblem

if TYPE_CHECKING:
    from fleetctl.run.teams.coordinator import TeamsFlight


class Handovers:
    """The hand-overs of one run of several teams (see the module docstring)."""

    def __init__(self, teams: TeamsFlight) -> None:
        self.teams = teams
        self.lock = asyncio.Lock()  # one hand-over at a time (each reads the decks left)

    async def carrier_lost(self, cid: str, run: TeamRun, after: float) -> None:
        """``cid``'s carrier has been lost ``after`` s: its pooled tasks leave it."""
        ex = run.executor
        if ex is None:
            return
        pooled = [
            e.task
            for e in ex.board.entries.values()
            if e.status == TaskStatus.POOLED and self.teams.board.owner.get(e.task.id) == cid
        ]
        self.teams.journal.write(
            Ev.CARRIER_LOST,
            vehicle=cid,
            text=f"{cid}: carrier lost for {after:g} s: "
            f"handing over {', '.join(t.id for t in pooled) or 'nothing'}",
        )
        if not pooled:
            return
        ex.submit_task_change(add=[], remove=[t.id for t in pooled], source="teams: carrier lost")
        await self.place(pooled, cid, f"{cid}'s carrier lost for more than {after:g} s")

    async def place(self, tasks: list[Task], from_team: str, why: str) -> None:
        async with self.lock:
            await self._place(tasks, from_team, why)

    async def _place(self, tasks: list[Task], from_team: str, why: str) -> None:
        tm, board = self.teams, self.teams.board
        refused = {cid for t in tasks for cid in board.gave_up.get(t.id, ())}  # no task goes back
        free = {
            cid: self._free_rovers(cid)
            for cid, e in board.teams.items()
            if cid != from_team and cid not in refused and e.can_receive
        }
        free = {cid: rovers for cid, rovers in free.items() if rovers}
        room = sum(len(r) for r in free.values())
        if not free:
            board.handovers.append(Handover([t.id for t in tasks], from_team, None, why, tm.clock()))
            tm.journal.write(
                Ev.HANDOVER,
                tasks=[t.id for t in tasks],
                from_team=from_team,
                to_team=None,
                why=why,
                text=f"no team can take {', '.join(t.id for t in tasks)} ({why})",
            )
            return
        take = tasks[:room]
        shares = await self._share(take, free)
        for cid, share in shares.items():
            if not share:
                continue
            deploying = board.teams[cid].status == TeamStatus.DEPLOYING  # else: a further round
            board.hand_over(share, from_team, cid, why, tm.clock())
            ids = [t.id for t in share]
            tm.journal.write(
                Ev.HANDOVER,
                tasks=ids,
                from_team=from_team,
                to_team=cid,
                why=why,
                text=f"{', '.join(ids)}: {from_team} -> {cid} ({why})",
            )
            run = tm.runs["deploy"][cid]
            if deploying and run.executor is not None:
                run.executor.submit_task_change(add=share, remove=[], source=f"team {from_team}")
        if len(take) < len(tasks):
            rest = [t.id for t in tasks[len(take) :]]
            board.handovers.append(Handover(rest, from_team, None, why, tm.clock()))
            tm.journal.write(
                Ev.HANDOVER,
                tasks=rest,
                from_team=from_team,
                to_team=None,
                why=why,
                text=f"no rover left on any deck for {', '.join(rest)}",
            )

    def _free_rovers(self, cid: str) -> list[str]:
        """The rovers on ``cid``'s deck its own pooled and handed tasks do not need."""
        run = self.teams.runs.get("deploy", {}).get(cid)
        if run is None:
            return []
        ex = run.executor
        if ex is None:
            return self._roster_left(cid)
        if run.fleet is None or run.fleet.carrier.lost:
            return []
        b, rovers = ex.board, run.fleet.rovers
        # the deck as its deployment found it (a driving carrier's deck is not told from telemetry)
        phase = ex.deploy_phase
        deck = phase.deck if phase is not None else [r for r, v in rovers.items() if rover_on_deck(ex.ctx, v)]
        deck = [rid for rid in deck if rid in rovers and b.available(rid) and not rovers[rid].lost]
        waiting = [t for t in self.teams.board.teams[cid].received if t.id not in b.entries]
        return deck[len(b.pooled()) + len(waiting) :]

    def _roster_left(self, cid: str) -> list[str]:
        """A team still starting (connecting, preflight: no deployment yet): the rovers of its
        roster that its share and the tasks already handed to it leave over (handed tasks wait on
        the team board and are flown as a further round once its share is done)."""
        fleet, e = self.teams.fleet, self.teams.board.teams[cid]
        if fleet is None or cid not in fleet.vehicles or fleet.vehicles[cid].lost:
            return []
        rovers = [rid for rid in e.rovers if rid in fleet.vehicles and not fleet.vehicles[rid].lost]
        return rovers[len(e.tasks) + len(e.received) :]

    async def _share(self, tasks: list[Task], free: dict[str, list[str]]) -> dict[str, list[Task]]:
        """Plan ``tasks`` over the teams with rovers ``free``: each team's share."""
        tm = self.teams
        if len(free) == 1:
            return {next(iter(free)): tasks}
        from planners import DEPLOY_PLANNERS

        name = tm.opts.planner or tm.mission.planner_for("deploy")
        problems = []
        for cid, rovers in free.items():
            run = tm.runs["deploy"][cid]
            own = dataclasses.replace(run.mission, tasks=tuple(tasks)).deploy_problem()
            if run.executor is not None:  # its live pose; a team still starting is at its mission's start
                start, heading = run.executor.carrier.pose()
                own = dataclasses.replace(own, start=start, heading=heading)
            problems.append(dataclasses.replace(own, rovers=tuple(rovers)))
        teams = TeamsProblem(tuple(free), tuple(problems))
        try:
            plan = await asyncio.to_thread(share_teams, teams, DEPLOY_PLANNERS[name], name)
        except Exception:  # noqa: BLE001 - cannot plan: the team with the most rovers left takes them
            best = max(free, key=lambda c: len(free[c]))
            return {best: tasks}
        by_id = {t.id: t for t in tasks}
        return {
            t.carrier: [by_id[leg.task] for leg in t.plan.legs() if leg.task in by_id] for t in plan.teams
        }


__all__ = ["Handovers"]
