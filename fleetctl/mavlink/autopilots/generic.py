"""Any other autopilot: standard commands only; custom modes raise ModeError."""

from __future__ import annotations

from fleetctl.mavlink.autopilots.base import Autopilot


class GenericAutopilot(Autopilot):
    name = "generic"
