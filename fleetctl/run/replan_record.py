"""A replan record: why the plan changed, the old and the new plan, and the latency from the event
to the first command of the new plan (the operator's measure of how fast the fleet reacts).

A phase calls :meth:`ReplanTracker.begin` when an event throws the rest of its plan away,
:meth:`ReplanTracker.ready` once the new plan exists (``None``: nothing is left to plan), and the
run context calls :meth:`ReplanTracker.on_command` before every command: the first command after
``ready`` closes the record (journalled as ``replan`` and shown in the view).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

from fleetctl.run.kinds import Ev

if TYPE_CHECKING:
    from fleetctl.run.state import FleetState
    from fleetctl.run.supervisor import SupervisorEvent
    from planners.core.plan import Plan


class _Recorder(Protocol):
    def __call__(self, kind: str, **data: Any) -> None: ...


@dataclass
class Replan:
    cause: str
    t: float  # time.monotonic of the event
    vehicle: str | None
    old: Plan | None
    new: Plan | None = None
    ready: bool = False


class ReplanTracker:
    """The one replan whose first command is not sent yet (see the module docstring)."""

    def __init__(self, state: FleetState, record: _Recorder) -> None:
        self.state = state
        self.record = record
        self.pending: Replan | None = None

    def begin(self, cause: str, ev: SupervisorEvent, old: Plan | None) -> None:
        if self.pending is not None:  # a second cause before the first plan went out: one replan
            self.pending.cause += f"; {cause}"
            return
        self.pending = Replan(cause, ev.t, ev.vehicle, old)

    def ready(self, new: Plan | None) -> None:
        r = self.pending
        if r is None:
            return
        r.new, r.ready = new, True
        if new is None:
            self.finish(None)

    def on_command(self) -> None:
        if self.pending is not None and self.pending.ready:
            self.finish((time.monotonic() - self.pending.t) * 1000.0)

    def finish(self, latency_ms: float | None) -> None:
        r, self.pending = self.pending, None
        if r is None:
            return
        st = self.state
        st.replans += 1
        lat = "" if latency_ms is None else f", first new command {latency_ms:.0f} ms after the event"
        what = (
            f"{len(r.new.stops)} stops, makespan {r.new.makespan:.1f} s"
            if r.new is not None
            else "nothing left to plan"
        )
        text = f"replan #{st.replans}: {r.cause} -> {what}{lat}"
        st.last_replan = text
        self.record(
            Ev.REPLAN,
            n=st.replans,
            cause=r.cause,
            latency_ms=latency_ms,
            old_plan=r.old.to_json() if r.old is not None else None,
            new_plan=r.new.to_json() if r.new is not None else None,
        )
        st.event(Ev.REPLAN, text, r.vehicle, n=st.replans, cause=r.cause, latency_ms=latency_ms)


__all__ = ["Replan", "ReplanTracker"]
