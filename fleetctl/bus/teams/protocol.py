"""The team coordination protocol: topics under the mission prefix ``P``, payloads, validation.

* ``P/teams/<team>/status`` (retained, last will ``offline``) - the team's
  :class:`~fleetctl.bus.client.FleetBus` status (its prefix is ``P/teams/<team>``) with the
  team's identity: ``team``, ``session`` (one per controller start), ``allocation`` (hash of the
  shared allocation), ``vehicles`` (``sim`` when its vehicles are an embedded simulator that dies
  with the controller, else ``real``) and ``carrier``;
* ``P/teams/<team>/progress`` (retained) - ``{"team", "session", "reached", "flying", "pooled",
  "free", "t"}``;
* ``P/claims/<task>`` (retained) - ``{"task", "team", "session", "epoch", "t"}`` (and
  ``"released": true`` when the team gives the task up): who flies the task;
* ``P/allocation`` (retained) - ``{"hash", "teams": {team: [task, ...]}, "t"}``, for operators.

Every payload is outside input: at most :data:`MAX_PEER_MESSAGE` bytes, nested at most
:data:`MAX_PEER_DEPTH` deep, every field typed, every team and task id one of the mission's.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

MAX_PEER_MESSAGE = 16 * 1024  # bytes of one coordination message
MAX_PEER_DEPTH = 4  # nesting of lists/objects in one
MAX_ID = 64  # characters of a team, task or session id


class TeamState(StrEnum):
    """What one controller knows of a team (its ``status`` topic)."""

    UNKNOWN = "unknown"  # nothing heard yet
    ONLINE = "online"
    DONE = "done"
    FAILED = "failed"
    INTERRUPTED = "interrupted"
    OFFLINE = "offline"  # the broker published its last will

    @property
    def gone(self) -> bool:
        """The team's controller flies no more (its unreached tasks may be handed over)."""
        return self in (TeamState.DONE, TeamState.FAILED, TeamState.INTERRUPTED, TeamState.OFFLINE)


class ClaimState(StrEnum):
    """One of this controller's own claims."""

    PENDING = "pending"  # published (or queued while the broker is away), not back from the broker yet
    HELD = "held"  # back from the broker and no better claim seen: the team may fly the task
    LOST = "lost"  # another team's better claim


class PeerMessageError(ValueError):
    """A coordination message that is ignored (journaled as ``team_message_rejected``)."""


@dataclass(frozen=True)
class Claim:
    task: str
    team: str
    session: str
    epoch: int
    t: float
    released: bool = False  # the team gives the task up (its carrier is lost): another team may claim it

    def payload(self) -> dict[str, Any]:
        return {"task": self.task, "team": self.team, "session": self.session, "epoch": self.epoch,
                "t": round(self.t, 3), **({"released": True} if self.released else {})}


def claim_key(claim: Claim, order: Sequence[str]) -> tuple[int, int]:
    """The conflict rule: the higher epoch wins; at the same epoch, the team earlier in the
    mission's ``carriers:`` list."""
    return claim.epoch, -order.index(claim.team)


@dataclass(frozen=True)
class StatusMsg:
    team: str
    state: TeamState
    session: str | None
    allocation: str | None
    vehicles: str | None
    carrier_lost: bool
    carrier_enu: tuple[float, float] | None
    t: float | None


@dataclass(frozen=True)
class ProgressMsg:
    team: str
    session: str
    reached: frozenset[str]
    flying: frozenset[str]
    pooled: frozenset[str]
    free: int
    t: float


class Topics:
    """The coordination topics of a mission prefix ``P``."""

    def __init__(self, prefix: str) -> None:
        self.prefix = prefix.strip("/")

    def team_prefix(self, team: str) -> str:
        return f"{self.prefix}/teams/{team}"

    def status(self, team: str = "+") -> str:
        return f"{self.team_prefix(team)}/status"

    def progress(self, team: str = "+") -> str:
        return f"{self.team_prefix(team)}/progress"

    def claim(self, task: str = "+") -> str:
        return f"{self.prefix}/claims/{task}"

    @property
    def allocation(self) -> str:
        return f"{self.prefix}/allocation"

    def kind_of(self, topic: str) -> tuple[str, str] | None:
        """``("status" | "progress", team)`` or ``("claim", task)`` for a coordination topic."""
        head = self.prefix + "/"
        if not topic.startswith(head):
            return None
        parts = topic[len(head):].split("/")
        if len(parts) == 3 and parts[0] == "teams" and parts[2] in ("status", "progress"):
            return parts[2], parts[1]
        if len(parts) == 2 and parts[0] == "claims":
            return "claim", parts[1]
        return None


def allocation_hash(mission_name: str, shares: Mapping[str, Sequence[str]]) -> str:
    """The same for every controller that computed the same allocation of the same mission."""
    text = json.dumps({"mission": mission_name, "teams": {k: list(v) for k, v in sorted(shares.items())}},
                      sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


# -- validation ---------------------------------------------------------------------------------------
def load(payload: bytes) -> dict[str, Any]:
    """A bounded JSON object (PeerMessageError otherwise)."""
    from fleetctl.bus.task_messages import bounded_json

    data = bounded_json(payload, MAX_PEER_MESSAGE, MAX_PEER_DEPTH, PeerMessageError)
    if not isinstance(data, dict):
        raise PeerMessageError("expected a JSON object")
    return data


def _id(data: dict[str, Any], key: str, known: Sequence[str] | frozenset[str] | None = None,
        optional: bool = False) -> str | None:
    v = data.get(key)
    if v is None and optional:
        return None
    if not isinstance(v, str) or not v or len(v) > MAX_ID:
        raise PeerMessageError(f"{key}: expected an id (a string of 1..{MAX_ID} characters)")
    if known is not None and v not in known:
        raise PeerMessageError(f"{key}: {v!r} is not one of the mission's")
    return v


def _time(data: dict[str, Any], key: str = "t") -> float:
    v = data.get(key)
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) or v < 0:
        raise PeerMessageError(f"{key}: expected a time (a non-negative number)")
    return float(v)


def _ids(data: dict[str, Any], key: str, known: frozenset[str]) -> frozenset[str]:
    v = data.get(key, [])
    if not isinstance(v, list) or len(v) > len(known) or not all(isinstance(x, str) for x in v):
        raise PeerMessageError(f"{key}: expected a list of task ids")
    unknown = [x for x in v if x not in known]
    if unknown:
        raise PeerMessageError(f"{key}: unknown task id(s) {', '.join(map(repr, unknown[:5]))}")
    return frozenset(v)


def parse_claim(task: str, payload: bytes, teams: Sequence[str], tasks: frozenset[str]) -> Claim:
    if task not in tasks:
        raise PeerMessageError(f"claim of {task!r}, which is no task of the mission")
    d = load(payload)
    if d.get("task") != task:
        raise PeerMessageError(f"task: {d.get('task')!r} does not match the topic's {task!r}")
    epoch = d.get("epoch")
    if isinstance(epoch, bool) or not isinstance(epoch, int) or not 0 <= epoch <= 10_000:
        raise PeerMessageError("epoch: expected an integer 0..10000")
    team, session = _id(d, "team", teams), _id(d, "session")
    assert team is not None and session is not None
    released = d.get("released", False)
    if not isinstance(released, bool):
        raise PeerMessageError("released: expected true or false")
    return Claim(task, team, session, epoch, _time(d), released)


def parse_status(team: str, payload: bytes, teams: Sequence[str]) -> StatusMsg:
    if team not in teams:
        raise PeerMessageError(f"status of {team!r}, which is no team of the mission")
    d = load(payload)
    try:
        state = TeamState(str(d.get("status")))
    except ValueError:
        raise PeerMessageError(f"status: {d.get('status')!r} is not one of "
                               f"{', '.join(s.value for s in TeamState)}") from None
    if d.get("team", team) != team:
        raise PeerMessageError(f"team: {d.get('team')!r} does not match the topic's {team!r}")
    vehicles = d.get("vehicles")
    if vehicles not in (None, "sim", "real"):
        raise PeerMessageError('vehicles: expected "sim" or "real"')
    lost, enu = _carrier(d.get("carrier"))
    t = _time(d) if "t" in d else None
    return StatusMsg(team, state, _id(d, "session", optional=True), _id(d, "allocation", optional=True),
                     vehicles, lost, enu, t)


def _carrier(c: Any) -> tuple[bool, tuple[float, float] | None]:
    if c is None:
        return False, None
    if not isinstance(c, dict):
        raise PeerMessageError("carrier: expected an object")
    lost = c.get("lost", False)
    if not isinstance(lost, bool):
        raise PeerMessageError("carrier.lost: expected true or false")
    enu = c.get("enu")
    if enu is None:
        return lost, None
    if not isinstance(enu, list) or len(enu) != 3 or not all(_number(x) for x in enu):
        raise PeerMessageError("carrier.enu: expected [east, north, up] in metres")
    return lost, (float(enu[0]), float(enu[1]))


def _number(x: Any) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)


def parse_progress(team: str, payload: bytes, teams: Sequence[str], tasks: frozenset[str]) -> ProgressMsg:
    if team not in teams:
        raise PeerMessageError(f"progress of {team!r}, which is no team of the mission")
    d = load(payload)
    if d.get("team") != team:
        raise PeerMessageError(f"team: {d.get('team')!r} does not match the topic's {team!r}")
    free = d.get("free")
    if isinstance(free, bool) or not isinstance(free, int) or not 0 <= free <= 10_000:
        raise PeerMessageError("free: expected a count of rovers")
    session = _id(d, "session")
    assert session is not None
    return ProgressMsg(team, session, _ids(d, "reached", tasks), _ids(d, "flying", tasks),
                       _ids(d, "pooled", tasks), free, _time(d))


__all__ = ["MAX_PEER_DEPTH", "MAX_PEER_MESSAGE", "Claim", "ClaimState", "PeerMessageError", "ProgressMsg",
           "StatusMsg", "TeamState", "Topics", "allocation_hash", "claim_key", "load", "parse_claim",
           "parse_progress", "parse_status"]
