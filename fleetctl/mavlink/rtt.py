"""How long to wait for a reply on a link before sending again: a retransmission timeout from the
round trips measured on it (RFC 6298's estimator: a smoothed round trip plus four times its mean
deviation), never below :data:`MIN_RTO` nor above the protocol's own timeout. On a lossy link a
lost request is then resent after a few round trips instead of a fixed second; before any round
trip is measured the protocol's timeout applies."""

from __future__ import annotations

MIN_RTO = 0.05  # s: shortest wait before a resend: an autopilot answers a command or a mission item
# within milliseconds on a wire or a local network, and a resend it did not need is answered again
# (the command protocol's ``confirmation``, the mission protocol's re-requested item); on a radio
# link the measured round trips, not this floor, set the wait
ALPHA, BETA = 1 / 8, 1 / 4  # RFC 6298's gains for the smoothed round trip and its deviation


class RoundTrip:
    """The round trips of one link (a command's ACK, a mission item's answer)."""

    def __init__(self) -> None:
        self.srtt: float | None = None
        self.rttvar = 0.0
        self.samples = 0

    def add(self, rtt: float) -> None:
        """One measured round trip (only of an exchange answered at its first attempt: a reply to a
        resent request could answer either)."""
        if rtt < 0:
            return
        self.samples += 1
        if self.srtt is None:
            self.srtt, self.rttvar = rtt, rtt / 2
            return
        self.rttvar = (1 - BETA) * self.rttvar + BETA * abs(self.srtt - rtt)
        self.srtt = (1 - ALPHA) * self.srtt + ALPHA * rtt

    def timeout(self, ceiling: float) -> float:
        """The wait before a resend: ``ceiling`` until a round trip is known, else the estimate
        within [MIN_RTO, ceiling]."""
        if self.srtt is None:
            return ceiling
        return min(ceiling, max(MIN_RTO, self.srtt + 4 * self.rttvar))


__all__ = ["MIN_RTO", "RoundTrip"]
