"""One team's link to the other teams' controllers over the MQTT bus (docs/mqtt.md#teams).

:class:`TeamLink` rides on the run's :class:`~fleetctl.bus.client.FleetBus` (whose prefix is
``P/teams/<team>``, so its retained status and last will are the team's presence): it subscribes
to every team's status and progress and to the task claims, publishes this team's progress and
claims, and acts on :class:`~fleetctl.bus.teams.board.ClaimBoard`'s rules once per
:data:`TICK` in one owned background task: tasks of a gone team are split, claimed, and once
held handed to the running deployment (``Executor.submit_task_change``); a claim lost to a
better one takes the task out again if no rover flies to it yet.

Flying never waits on the broker: the share the allocation gave this team is its own from the
start, claims made while the broker is away are queued by the bus and published when it is back,
and a claimed task is flown only once the broker has confirmed the claim.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
import uuid
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

from fleetctl.bus.teams.board import HANDOVER_GRACE, ClaimBoard
from fleetctl.bus.teams.protocol import (
    Claim,
    ClaimState,
    PeerMessageError,
    TeamState,
    Topics,
    allocation_hash,
    parse_claim,
    parse_progress,
    parse_status,
)
from fleetctl.mission import Mission
from fleetctl.mission.teams import mission_teams, own_mission, team_of
from fleetctl.run.kinds import Ev, VehicleStatus
from fleetctl.run.task_board import TaskStatus
from planners.core.problem import CarrierSpec

if TYPE_CHECKING:
    from fleetctl.bus.client import FleetBus
    from fleetctl.run.executor import Executor
    from fleetctl.run.state import Event, FleetState

log = logging.getLogger(__name__)

TICK = 0.2  # s between two looks at the board
UNCLAIMED_AFTER = 3.0  # s an orphan the split gave another team may stay unclaimed before we claim it
CARRIER_RELEASE_AFTER = 5.0  # wall s the carrier's link is lost before its unlaunched tasks are given up
STANDBY_POLL = 1.0  # s: a finished team looks again for handed-over work this often
CLOSE_TIMEOUT = 2.0  # s for the loop to end on shutdown
MAX_REJECT_RECORDS = 50  # journal records of ignored coordination messages (then only counted)


class TeamLink:
    """The coordination of one team (see the module docstring)."""

    def __init__(self, mission: Mission, team: str, shares: Mapping[str, Sequence[str]], prefix: str,
                 vehicles: str, rovers: Sequence[str]) -> None:
        order = tuple(t.carrier.id for t in mission_teams(mission))
        self.mission, self.team, self.vehicles = mission, team, vehicles
        self.rovers = tuple(rovers)
        self.shares = {k: list(v) for k, v in shares.items()}
        self.topics = Topics(prefix)
        self.tasks = {t.id: t for t in mission.tasks}
        self.task_ids = frozenset(self.tasks)
        owner = {task: k for k, ids in self.shares.items() for task in ids}
        teams = {t.carrier.id: t.carrier for t in mission_teams(mission)}
        self.board = ClaimBoard(
            team, uuid.uuid4().hex[:12], order, tuple(self.tasks), owner,
            allocation_hash(mission.name, self.shares),
            carriers={k: _carrier_spec(mission, k) for k in teams},
            starts={k: _start(mission, k) for k in teams},
            targets={t.id: t.position for t in mission.tasks})
        self.bus: FleetBus | None = None
        self.executor: Executor | None = None
        self.state: FleetState | None = None
        self.record: Callable[..., None] = lambda kind, **data: None
        self.delivered: list[str] = []  # handed-over tasks given to our deployment, in order
        self._undelivered: list[str] = []  # held before the executor existed
        self.rejected = 0
        self.handovers: list[dict[str, Any]] = []
        self._progress_sent: tuple[Any, ...] | None = None
        self._peer_seen: dict[str, TeamState] = {}
        self._task: asyncio.Task[None] | None = None
        self._wake = asyncio.Event()
        self._carrier_lost_since: float | None = None
        self._orphan_since: dict[str, float] = {}  # task -> when first seen orphaned
        self._batches = 0
        self._sent: dict[str, list[str]] = {}  # source of a handed-over batch -> its tasks
        self.released: list[str] = []  # tasks we gave up (our carrier lost, or our deployment refused them)
        self.resumed: dict[str, int] = {}  # a resumed controller: handed-over task -> epoch it held it at

    # -- wiring ----------------------------------------------------------------------------------
    @property
    def session(self) -> str:
        return self.board.session

    def prepare(self, bus: FleetBus) -> None:
        """Before the bus starts: the team's identity in its status and last will, the subscriptions."""
        self.bus = bus
        bus.identity = {"team": self.team, "session": self.session, "allocation": self.board.alloc_hash,
                        "vehicles": self.vehicles}
        for topic in (self.topics.status(), self.topics.progress(), self.topics.claim()):
            bus.subscribe(topic, self.on_message)

    def start(self, state: FleetState, record: Callable[..., None]) -> None:
        """Publish the allocation and our share's claims; start the loop (needs a running loop)."""
        self.state, self.record = state, record
        state.add_listener(self._on_event)
        now, t = time.monotonic(), time.time()
        allocation = {"hash": self.board.alloc_hash, "mission": self.mission.name, "teams": self.shares,
                      "t": round(t, 3)}
        self._bus().publish(self.topics.allocation, allocation, retain=True, qos=1, absolute=True)
        for task in self.shares.get(self.team, []):
            if task not in self.released:
                self._publish_claim(self.board.make_claim(task, 0, t, now, held=True))
        for task, epoch in self.resumed.items():  # re-joining: the claims held when the controller stopped
            self._publish_claim(self.board.make_claim(task, epoch, t, now, held=True))
            self.delivered.append(task)
            record(Ev.TEAM_CLAIM, op="resumed", task=task, epoch=epoch)
        self._publish_progress()
        record(Ev.TEAM, team=self.team, session=self.session, allocation=self.board.alloc_hash,
               share=self.shares.get(self.team, []), teams=list(self.board.order), prefix=self.topics.prefix)
        self._task = asyncio.get_running_loop().create_task(self._loop(), name="team link")

    def resume(self, records: Sequence[Mapping[str, Any]]) -> None:
        """A resumed controller (before :meth:`start`): from its journal's records, the handed-over
        tasks it held claims on (re-claimed at their epochs when it starts) and the tasks it had
        given up (not claimed again)."""
        for r in records:
            task = r.get("task")
            if r.get("kind") == "team_claim" and isinstance(task, str) and task in self.tasks:
                if r.get("op") == "held":
                    self.resumed[task] = int(r.get("epoch") or 0)
                elif r.get("op") == "lost":
                    self.resumed.pop(task, None)
            elif r.get("kind") == "team_release":
                for t in r.get("tasks") or []:
                    self.resumed.pop(str(t), None)
                    self.released.append(str(t))

    def attach_executor(self, executor: Executor) -> None:
        """The deployment to feed; tasks of our share that another team claimed better before it
        existed (e.g. it took them over while this controller was down) are taken out first."""
        self.executor = executor
        lost = [t for t, mc in self.board.mine.items()
                if mc.state == ClaimState.LOST and t in executor.board.entries]
        if lost:
            executor.submit_task_change(add=[], remove=lost, source=f"team:{self.team}")
            self._event(Ev.TEAM_CLAIM_LOST, f"team {self.team}: {', '.join(lost)} claimed by another team: "
                        "taken out of this deployment", None, tasks=lost)
        held, self._undelivered = self._undelivered, []
        self._deliver(held)

    async def close(self) -> None:
        """Stop the loop; the last progress goes out with the bus's final flush."""
        if self._task is not None:
            self._task.cancel()
            await asyncio.wait({self._task}, timeout=CLOSE_TIMEOUT)
            self._task = None
        self._publish_progress()
        self.record(Ev.TEAM_SUMMARY, **self.stats())

    def stats(self) -> dict[str, Any]:
        return {"team": self.team, "session": self.session, "allocation": self.board.alloc_hash,
                "share": self.shares.get(self.team, []), "handed_over": list(self.delivered),
                "handovers": self.handovers, "released": list(self.released), "rejected": self.rejected,
                "peers": {k: p.state.value for k, p in self.board.peers.items() if k != self.team},
                "claims_lost": [t for t, c in self.board.mine.items() if c.state == ClaimState.LOST]}

    # -- incoming --------------------------------------------------------------------------------
    def on_message(self, topic: str, payload: bytes) -> None:
        """A coordination message (called by the bus, in its error boundary); a bad one is ignored
        and journaled."""
        kind = self.topics.kind_of(topic)
        if kind is None:
            return
        what, name = kind
        now, b = time.monotonic(), self.board
        try:
            if what == "claim":
                if not payload:  # a cleared retained claim
                    return
                b.on_claim(parse_claim(name, payload, b.order, self.task_ids), now)
            elif what == "status":
                if b.on_status(parse_status(name, payload, b.order), now):
                    self._event(Ev.TEAM_MISMATCH, f"team {name}: runs another allocation of the tasks "
                                "(another mission file, seed or planner?); its claims and status are ignored",
                                name)
            elif name != self.team:
                b.on_progress(parse_progress(name, payload, b.order, self.task_ids))
        except PeerMessageError as exc:
            self.rejected += 1
            if self.rejected <= MAX_REJECT_RECORDS:
                self.record(Ev.TEAM_MESSAGE_REJECTED, topic=topic, error=str(exc),
                            payload=payload[:200].decode("utf-8", "replace"))
            log.warning("team link: ignored %s: %s", topic, exc)
        self._wake.set()

    def _on_event(self, ev: Event) -> None:
        """A run event: progress goes out at once when a task is reached or a rover launched (a
        peer must not hand over a task this team has just reached)."""
        if ev.kind in (Ev.TASK_REACHED, Ev.ROVER_LAUNCHED, Ev.TASKS_CHANGED):
            self._publish_progress()
        elif ev.kind == Ev.TASK_CHANGE_REJECTED and ev.data.get("source") in self._sent:
            ids = self._sent.pop(ev.data["source"])  # e.g. no rover left on the deck for them
            self._give_up(ids, f"its deployment refused them ({ev.data.get('reason')})")
            self._publish_progress()

    # -- the loop --------------------------------------------------------------------------------
    async def _loop(self) -> None:
        while True:
            try:
                self.tick()
            except Exception:  # noqa: BLE001 - one bad look never ends the coordination
                log.exception("team link: tick failed")
            await self._sleep(TICK)

    async def _sleep(self, seconds: float) -> None:
        """Until something arrives or ``seconds`` pass (``asyncio.timeout``: unlike ``wait_for``
        on Python 3.11 it never swallows a cancellation)."""
        self._wake.clear()
        with contextlib.suppress(TimeoutError):
            async with asyncio.timeout(seconds):
                await self._wake.wait()

    def tick(self) -> None:
        now = time.monotonic()
        self._peer_events()
        self._carrier_check(now)
        self._handover(now)
        held, lost = self.board.settle(now)
        for task in held:
            self._on_held(task)
        for task in lost:
            self._on_lost(task)
        for task in self.board.beaten():
            self._publish_claim(self.board.mine[task].claim)
        self._publish_progress()

    def _peer_events(self) -> None:
        for team, p in self.board.peers.items():
            if team == self.team or self._peer_seen.get(team, TeamState.UNKNOWN) == p.state:
                continue
            self._peer_seen[team] = p.state
            why = " (last will: its controller vanished)" if p.state == TeamState.OFFLINE else ""
            if p.state.gone and not p.seen_going:
                why += (" - not seen online by this controller (an earlier run, or it ended before this "
                        "one started): its tasks are not handed over")
            self._event(Ev.TEAM_PEER, f"team {team}: {p.state}{why}", team, state=p.state.value)

    def _handover(self, now: float) -> None:
        b = self.board
        orphans = [(t, e) for t, e in b.orphans(now)
                   if t not in b.mine or b.mine[t].state == ClaimState.LOST and b.mine[t].claim.epoch <= e]
        if not orphans:
            return
        free = {team: b.free_of(team) for team in b.online_teams() if team != self.team}
        mine = free[self.team] = self.free_for_new()
        split = b.split(orphans, free)
        t = time.time()
        for task, epoch in orphans:
            since = self._orphan_since.setdefault(task, now)
            ours = split.get(task) == self.team
            if not ours and mine > 0 and now - since >= UNCLAIMED_AFTER:
                ours = True  # the team the split named has not claimed it: the conflict rule settles it
            if not ours:
                continue
            mine -= 1
            gone, _ = b.owner(task)
            claim = b.make_claim(task, epoch + 1, t, now)
            self._publish_claim(claim)
            entry = {"task": task, "from": gone, "epoch": epoch + 1, "claimed_t": round(t, 3),
                     "gone_t": _gone_unix(b.peers[gone].gone_since, now, t)}
            self.handovers.append(entry)
            self.record(Ev.TEAM_CLAIM, op="claimed", **entry)

    def carrier_lost(self) -> bool:
        st = self.state
        c = st.vehicles.get(st.carrier_id) if st is not None else None
        return bool(c is not None and c.lost)

    def _carrier_check(self, now: float) -> None:
        """Our carrier's link lost for CARRIER_RELEASE_AFTER s: give up the tasks no rover of ours
        flies to yet (out of our deployment, released claims), so that the other teams fly them."""
        if not self.carrier_lost():
            self._carrier_lost_since = None
            return
        if self._carrier_lost_since is None:
            self._carrier_lost_since = now
        if now - self._carrier_lost_since < CARRIER_RELEASE_AFTER or self.executor is None:
            return
        b = self.board
        pooled = [t for t in self.executor.board.with_status(TaskStatus.POOLED)
                  if t in self.tasks and b.owner(t)[0] == self.team and t not in self.released]
        if not pooled:
            return
        self.executor.submit_task_change(add=[], remove=pooled, source=f"team:{self.team}")
        self._give_up(pooled, f"carrier lost for {CARRIER_RELEASE_AFTER:g} s")

    def _on_held(self, task: str) -> None:
        mc = self.board.mine[task]
        if mc.claim.epoch == 0:
            return
        for h in self.handovers:
            if h["task"] == task and h["epoch"] == mc.claim.epoch:
                h["held_t"] = round(time.time(), 3)
        self.record(Ev.TEAM_CLAIM, op="held", task=task, epoch=mc.claim.epoch)
        if self.executor is None:
            self._undelivered.append(task)
        else:
            self._deliver([task])

    def _deliver(self, ids: list[str]) -> None:
        if not ids:
            return
        tasks = [self.tasks[i] for i in ids]
        self.delivered.extend(ids)
        self._batches += 1
        source = f"team:{self.team}#{self._batches}"  # a rejection of this batch names it
        self._sent[source] = list(ids)
        self._event(Ev.TEAM_HANDOVER, f"team {self.team}: takes over {', '.join(ids)} (claimed)", None,
                    tasks=ids)
        assert self.executor is not None  # delivered once the deployment exists (attach_executor)
        self.executor.submit_task_change(add=tasks, remove=[], source=source)
        self._wake.set()

    def _give_up(self, ids: list[str], why: str) -> None:
        """Tasks we hold but cannot fly: released claims, so that another team may take them."""
        b, now, t = self.board, time.monotonic(), time.time()
        for task in ids:
            if task in self.delivered:
                self.delivered.remove(task)
            self._publish_claim(b.make_claim(task, b.owner(task)[1] + 1, t, now, released=True))
        self.released.extend(ids)
        self._event(Ev.TEAM_RELEASE, f"team {self.team}: {why}: gives up {', '.join(ids)} to the other teams",
                    None, tasks=ids)

    def _on_lost(self, task: str) -> None:
        best = self.board.best_claim(task)
        who = best.team if best is not None else "?"
        ex = self.executor
        entry = ex.board.entries.get(task) if ex is not None else None
        if task in self._undelivered:
            self._undelivered.remove(task)
        if ex is not None and entry is not None and entry.status == TaskStatus.POOLED:
            ex.submit_task_change(add=[], remove=[task], source=f"team:{who}")
            self._event(Ev.TEAM_CLAIM_LOST, f"team {self.team}: {task} is claimed by team {who}: "
                        "taken out of this deployment", None, task=task, by=who)
        elif entry is not None and entry.status in (TaskStatus.FLYING, TaskStatus.REACHED):
            self._event(Ev.TEAM_CLAIM_CONFLICT, f"team {self.team}: {task} is claimed by team {who} but a "
                        f"rover of this team is {entry.status} to it; it flies on", None, task=task, by=who)
        else:
            self.record(Ev.TEAM_CLAIM, op="lost", task=task, by=who)

    # -- outgoing --------------------------------------------------------------------------------
    def _bus(self) -> FleetBus:
        assert self.bus is not None, "prepare(bus) comes first"
        return self.bus

    def _publish_claim(self, claim: Claim) -> None:
        self._bus().publish(self.topics.claim(claim.task), claim.payload(), retain=True, qos=1, absolute=True)

    def progress(self) -> dict[str, Any]:
        """This team's reached, flying and pooled tasks and its rovers left on the deck."""
        board = self.executor.board if self.executor is not None else None
        if board is None:
            share = self.shares.get(self.team, [])
            return {"reached": [], "flying": [], "pooled": share + self._undelivered,
                    "free": len(self.rovers)}
        known = self.tasks  # tasks added over P/teams/<team>/tasks/add are the team's own business
        pooled = board.with_status(TaskStatus.POOLED)
        extra = sum(1 for t in pooled if t not in known)  # ... but they need rovers of its deck
        return {"reached": [t for t in board.with_status(TaskStatus.REACHED) if t in known],
                "flying": [t for t in board.with_status(TaskStatus.FLYING) if t in known],
                "pooled": [t for t in pooled if t in known] + self._queued(),
                "free": max(0, self.free_rovers() - extra)}

    def _queued(self) -> list[str]:
        """Handed-over tasks given to the deployment that it has not put on its board yet."""
        entries = self.executor.board.entries if self.executor is not None else {}
        return [t for t in self.delivered if t not in entries]

    def free_rovers(self) -> int:
        """Our rovers that may still be launched (on the deck, not lost, not used)."""
        ex = self.executor
        if ex is None:
            return len(self.rovers)
        vs = self.state.vehicles if self.state is not None else {}
        return sum(1 for r in self.rovers if ex.board.available(r) and not (r in vs and vs[r].lost)
                   and (r not in vs or vs[r].state in (VehicleStatus.ON_DECK, VehicleStatus.UNKNOWN)))

    def free_for_new(self) -> int:
        if self.carrier_lost():
            return 0
        p = self.progress()
        pending = sum(1 for mc in self.board.mine.values() if mc.state == ClaimState.PENDING)
        return max(0, p["free"] - len(p["pooled"]) - pending - len(self._undelivered))

    def _publish_progress(self) -> None:
        if self.bus is None:
            return
        p = self.progress()
        key = tuple(tuple(v) if isinstance(v, list) else v for v in p.values())
        if key == self._progress_sent:
            return
        self._progress_sent = key
        self.bus.publish(f"{self.topics.progress(self.team)}",
                         {"team": self.team, "session": self.session, **p, "t": round(time.time(), 3)},
                         retain=True, qos=1, absolute=True)

    def _event(self, kind: str, text: str, vehicle: str | None, **data: Any) -> None:
        if self.state is not None:
            self.state.event(kind, text, None, **({"team": vehicle} if vehicle else {}), **data)
        else:
            self.record(kind, text=text, **data)

    # -- after our own share ---------------------------------------------------------------------
    async def wait_for_work(self) -> bool:
        """After our deployment: True when handed-over tasks wait for another round; False when
        no more can come (no rover left, or no other team that may still hand tasks over)."""
        while True:
            if self._queued():
                return True
            if not self._may_get_work():
                return False
            await self._sleep(STANDBY_POLL)

    def _may_get_work(self) -> bool:
        b, now = self.board, time.monotonic()
        if self.free_rovers() <= 0:
            return False
        if any(mc.state == ClaimState.PENDING for mc in b.mine.values()) or self._undelivered:
            return True
        done = b.reached()
        for team, p in b.peers.items():
            if team == self.team or team in b.mismatched:
                continue
            owned = [t for t in self.tasks if b.owner(t)[0] == team and t not in done]
            if not owned:
                continue
            if p.state == TeamState.ONLINE:  # it may still go: stand by
                return True
            if p.seen_going and p.gone_since is not None and now - p.gone_since < HANDOVER_GRACE + 2 * TICK:
                return True  # gone: its tasks are handed over after the grace
        return False


def _gone_unix(gone_since: float | None, now: float, t: float) -> float | None:
    return None if gone_since is None else round(t - (now - gone_since), 3)


def _carrier_spec(mission: Mission, team: str) -> CarrierSpec:
    return own_mission(mission, team_of(mission, team).carrier).deploy_problem().carrier


def _start(mission: Mission, team: str) -> tuple[float, float, float]:
    x, y, z = own_mission(mission, team_of(mission, team).carrier).deploy_problem().start
    return float(x), float(y), float(z)


__all__ = ["TeamLink"]
