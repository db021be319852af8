"""What one team's controller knows of every team and every task claim, and the hand-over rules.

Pure state, no I/O (:mod:`fleetctl.run.teams.link` feeds it from the bus and acts on it). The
rules (docs/mqtt.md#teams):

* **Owner.** A task's owner is the team of its best *valid* claim (:func:`~.protocol.claim_key`:
  higher epoch, then the team earlier in ``carriers:``); a claim is valid while its session is
  the claiming team's current one (its status says which), so claims left on the broker by an
  earlier run count for nothing. Without a valid claim the owner is the team the shared
  allocation gave it (epoch 0: every controller computes the same allocation).
* **Orphans.** A task is orphaned when its owner's controller is gone (status ``offline`` - the
  last will -, ``failed``, ``interrupted`` or ``done``, in a session this controller saw online:
  a status an earlier run left on the broker hands nothing over) for :data:`HANDOVER_GRACE` s and
  nobody reached it, or when its owner released it (a ``released`` claim: its carrier is lost). A task
  the gone team had a rover flying to is orphaned only when that team's
  vehicles were an embedded simulator (they died with it): a real rover flies on to its task.
* **Split.** The orphans, in mission order, each go to the online team (allocation hash equal to
  ours, a free rover on its deck) whose carrier reaches it soonest by the time model
  (``planners.core.timing.carrier_step`` from the carrier's reported position), ties to the team
  earlier in ``carriers:``. Every controller with the same view computes the same split; where
  views differ the conflict rule settles it.
* A team claims its share of the orphans at the orphan's epoch + 1, and flies a claimed task only
  once its claim came back from the broker and no better one was seen for :data:`CLAIM_SETTLE` s.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from fleetctl.bus.teams.protocol import Claim, ClaimState, ProgressMsg, StatusMsg, TeamState, claim_key
from planners.core.problem import CarrierSpec
from planners.core.timing import carrier_step

HANDOVER_GRACE = 2.0  # s a team is gone before its tasks are handed over (a reconnecting peer comes back)
CLAIM_SETTLE = 0.3  # s a claim must stand, back from the broker, before its team flies the task


@dataclass
class Peer:
    """The latest of a team's status and progress."""

    team: str
    state: TeamState = TeamState.UNKNOWN
    session: str | None = None
    allocation: str | None = None
    vehicles: str | None = None
    carrier_lost: bool = False
    carrier_xy: tuple[float, float] | None = None
    heartbeat: float | None = None  # the status's Unix time
    gone_since: float | None = None  # monotonic: when it was first seen gone
    progress: ProgressMsg | None = None
    online_session: str | None = None  # the last session this controller saw online

    @property
    def seen_going(self) -> bool:
        """Gone, in a session this controller saw online (not a status left by an earlier run)."""
        return self.state.gone and self.session is not None and self.online_session == self.session


@dataclass
class MyClaim:
    claim: Claim
    state: ClaimState = ClaimState.PENDING
    echoed: float | None = None  # monotonic: when it came back from the broker
    made: float = 0.0  # monotonic


@dataclass
class ClaimBoard:
    me: str
    session: str
    order: tuple[str, ...]  # the mission's carriers, in order
    tasks: tuple[str, ...]  # the mission's task ids, in order
    allocation: Mapping[str, str]  # task -> team (the shared allocation)
    alloc_hash: str
    carriers: Mapping[str, CarrierSpec] = field(default_factory=dict)
    starts: Mapping[str, tuple[float, float, float]] = field(default_factory=dict)  # team -> carrier start
    targets: Mapping[str, tuple[float, float, float]] = field(default_factory=dict)  # task -> position
    peers: dict[str, Peer] = field(default_factory=dict)
    claims: dict[str, dict[str, Claim]] = field(default_factory=dict)  # task -> team -> its latest claim
    mine: dict[str, MyClaim] = field(default_factory=dict)
    mismatched: set[str] = field(default_factory=set)  # teams with another allocation (warned once)
    # (task, team) -> the t of the worse claim we last published over (one per task and team: bounded)
    answered: dict[tuple[str, str], float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for t in self.order:
            self.peers.setdefault(t, Peer(t))
        me = self.peers[self.me]
        me.state, me.session, me.allocation = TeamState.ONLINE, self.session, self.alloc_hash

    # -- what the bus says ------------------------------------------------------------------------
    def on_status(self, msg: StatusMsg, now: float) -> bool:
        """A team's status; True when it has another allocation than ours (first time only)."""
        if msg.team == self.me:
            return False
        p = self.peers[msg.team]
        if msg.session is not None and msg.session != p.session:
            p.session, p.progress = msg.session, None
        was_gone = p.state.gone
        p.state, p.vehicles = msg.state, msg.vehicles or p.vehicles
        p.carrier_lost, p.heartbeat = msg.carrier_lost, msg.t
        p.carrier_xy = msg.carrier_enu or p.carrier_xy
        p.allocation = msg.allocation or p.allocation
        if msg.state == TeamState.ONLINE:
            p.online_session = p.session
        if msg.state.gone and not was_gone:
            p.gone_since = now
        elif not msg.state.gone:
            p.gone_since = None
        if p.allocation is not None and p.allocation != self.alloc_hash and msg.team not in self.mismatched:
            self.mismatched.add(msg.team)
            return True
        return False

    def on_progress(self, msg: ProgressMsg) -> None:
        p = self.peers[msg.team]
        if msg.team != self.me and (p.session is None or msg.session == p.session):
            p.progress = msg

    def on_claim(self, claim: Claim, now: float) -> None:
        self.claims.setdefault(claim.task, {})[claim.team] = claim
        own = self.mine.get(claim.task)
        if own is not None and claim == own.claim and own.echoed is None:
            own.echoed = now

    # -- who flies what ---------------------------------------------------------------------------
    def valid(self, claim: Claim) -> bool:
        p = self.peers.get(claim.team)
        return (p is not None and claim.session == p.session and claim.team not in self.mismatched)

    def best_claim(self, task: str) -> Claim | None:
        valid = [c for c in self.claims.get(task, {}).values() if self.valid(c)]
        return max(valid, key=lambda c: claim_key(c, self.order), default=None)

    def owner(self, task: str) -> tuple[str, int]:
        """The task's owner and the epoch it owns it at."""
        best = self.best_claim(task)
        return (best.team, best.epoch) if best is not None else (self.allocation[task], 0)

    def reached(self) -> set[str]:
        return {t for p in self.peers.values() if p.progress is not None for t in p.progress.reached}

    def orphans(self, now: float) -> list[tuple[str, int]]:
        """Tasks to hand over (mission order) with the epoch their gone owner held them at."""
        done = self.reached()
        out = []
        for task in self.tasks:
            team, epoch = self.owner(task)
            p = self.peers[team]
            best = self.best_claim(task)
            if best is not None and best.released and task not in done:
                if team != self.me:
                    out.append((task, epoch))  # given up by its team (its carrier is lost)
                continue
            if team == self.me or task in done or team in self.mismatched or not p.seen_going:
                continue
            if p.gone_since is None or now - p.gone_since < HANDOVER_GRACE:
                continue
            flying = p.progress is not None and task in p.progress.flying
            if flying and p.vehicles != "sim":
                continue  # its rover flies on to it
            out.append((task, epoch))
        return out

    def online_teams(self) -> list[str]:
        return [t for t in self.order if t == self.me or (self.peers[t].state == TeamState.ONLINE
                                                          and t not in self.mismatched)]

    def split(self, orphans: Sequence[tuple[str, int]], free: Mapping[str, int]) -> dict[str, str]:
        """task -> the online team that takes it (see the module docstring); ``free`` is each
        team's rovers left for new tasks (a team missing from it has none)."""
        left = {t: free.get(t, 0) for t in self.online_teams()}
        out: dict[str, str] = {}
        for task, _ in orphans:
            best: tuple[float, int, str] | None = None
            for k, team in enumerate(self.order):
                if left.get(team, 0) <= 0:
                    continue
                cand = (self._reach_time(team, task), k, team)
                best = cand if best is None or cand < best else best
            if best is not None:
                out[task] = best[2]
                left[best[2]] -= 1
        return out

    def _reach_time(self, team: str, task: str) -> float:
        spec, target = self.carriers.get(team), self.targets.get(task)
        if spec is None or target is None:
            return 0.0
        p = self.peers[team]
        x, y = p.carrier_xy or self.starts.get(team, (0.0, 0.0, 0.0))[:2]
        return carrier_step(target[0] - x, target[1] - y, 0.0, spec)[0]

    def free_of(self, team: str) -> int:
        """A peer's rovers left for new tasks (from its progress)."""
        p = self.peers[team]
        pr = p.progress
        return 0 if pr is None or p.carrier_lost else max(0, pr.free - len(pr.pooled))

    # -- our own claims ---------------------------------------------------------------------------
    def make_claim(self, task: str, epoch: int, t: float, now: float, held: bool = False,
                   released: bool = False) -> Claim:
        """Our claim of ``task`` at ``epoch``; ``held``: ours already (the shared allocation's);
        ``released``: we give it up."""
        c = Claim(task, self.me, self.session, epoch, round(t, 3), released)  # as its payload carries it
        self.mine[task] = MyClaim(c, ClaimState.HELD if held or released else ClaimState.PENDING, made=now)
        return c

    def settle(self, now: float) -> tuple[list[str], list[str]]:
        """Update our claims: (newly held, newly lost) task ids."""
        held, lost = [], []
        for task, mc in self.mine.items():
            if mc.state == ClaimState.LOST:
                continue
            best = self.best_claim(task)
            if best is not None and best.team != self.me and (
                    claim_key(best, self.order) > claim_key(mc.claim, self.order)):
                mc.state = ClaimState.LOST
                lost.append(task)
            elif (mc.state == ClaimState.PENDING and mc.echoed is not None
                  and now - mc.echoed >= CLAIM_SETTLE):
                mc.state = ClaimState.HELD
                held.append(task)
        return held, lost

    def beaten(self) -> list[str]:
        """Our live claims that a worse claim overwrote on the broker since (to publish again, once
        per such claim), so that the retained value names the winner."""
        out = []
        for task, mc in self.mine.items():
            if mc.state == ClaimState.LOST:
                continue
            for team, c in self.claims.get(task, {}).items():
                if (team != self.me and c.t > self.answered.get((task, team), -1.0) and c.t >= mc.claim.t
                        and claim_key(c, self.order) < claim_key(mc.claim, self.order)):
                    self.answered[(task, team)] = c.t
                    out.append(task)
                    break
        return out

__all__ = ["CLAIM_SETTLE", "HANDOVER_GRACE", "MyClaim", "Peer", "ClaimBoard"]
