"""The errors of a MAVLink link: it cannot be used (:class:`LinkError`), a vehicle did not answer
after every retry (:class:`LinkTimeout`), a vehicle refused a mission transfer
(:class:`MissionRejected`)."""

from __future__ import annotations

from fleetctl.mavlink.messages import enum_name


class LinkError(Exception):
    """A link that cannot be opened or used (bad URL, port in use, unreachable peer)."""


class LinkTimeout(LinkError, TimeoutError):
    """No (final) reply from a vehicle after every retry."""


class MissionRejected(LinkError):
    """The vehicle ended a mission transfer with an error MISSION_ACK (final, per the spec)."""

    def __init__(self, sysid: int, operation: str, result: int) -> None:
        self.sysid = sysid
        self.operation = operation
        self.result = result
        self.result_name = enum_name("MAV_MISSION_RESULT", result)
        self.reason: str | None = None  # the autopilot's STATUSTEXT, when the vehicle proxy saw one
        super().__init__(f"system {sysid} rejected the mission {operation}: {self.result_name}")


__all__ = ["LinkError", "LinkTimeout", "MissionRejected"]
