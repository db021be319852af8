"""The parts of a run every phase flies with: the context, the carrier, supervision, planning."""

from __future__ import annotations

from dataclasses import dataclass

from fleetctl.run.carrier import CarrierControl
from fleetctl.run.context import RunContext
from fleetctl.run.planning import Planning
from fleetctl.run.supervisor import Supervisor


@dataclass(frozen=True)
class PhaseParts:
    ctx: RunContext
    carrier: CarrierControl
    supervisor: Supervisor
    planning: Planning


__all__ = ["PhaseParts"]
