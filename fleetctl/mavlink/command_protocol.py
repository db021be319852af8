"""The MAVLink command protocol on a link: :func:`send_command` (COMMAND_LONG or COMMAND_INT, resent
with ``confirmation`` incremented until a COMMAND_ACK, a longer wait after MAV_RESULT_IN_PROGRESS)
and :func:`set_message_interval`. One command of a kind per vehicle at a time."""

from __future__ import annotations

import logging
import time
from collections.abc import Iterable
from typing import TYPE_CHECKING

from pymavlink.dialects.v20 import ardupilotmega as M

from fleetctl.mavlink.errors import LinkTimeout
from fleetctl.mavlink.messages import CommandAck, command_name, deg_e7

if TYPE_CHECKING:
    from fleetctl.mavlink.channel import Channel

log = logging.getLogger(__name__)

COMMAND_TIMEOUT = 1.0  # s per attempt
COMMAND_RETRIES = 7  # resends after the first attempt: with 20 % loss each way an attempt fails
# 36 % of the time; 8 attempts leave 0.03 % (5 left 0.6 %, about one failed launch in four lossy runs)
COMMAND_PROGRESS_TIMEOUT = 10.0  # s to wait for the final ACK after MAV_RESULT_IN_PROGRESS


async def send_command(
    link: Channel, sysid: int, command: int, params: Iterable[float] = (), *, compid: int = 1,
    frame: int | None = None, timeout: float = COMMAND_TIMEOUT, retries: int = COMMAND_RETRIES,
    progress_timeout: float = COMMAND_PROGRESS_TIMEOUT,
) -> CommandAck:
    """Send a command and return its final :class:`CommandAck` (any result; check ``accepted``).

    ``params`` are param1..param7. ``frame=None`` sends COMMAND_LONG (resent with
    ``confirmation`` incremented); a frame sends COMMAND_INT with param5/param6 as latitude/
    longitude in degrees (encoded ·1e7) and param7 as z. After MAV_RESULT_IN_PROGRESS the
    final ACK is awaited up to ``progress_timeout``. An attempt waits ``timeout`` until the link
    has measured its round trips, then the link's retransmission timeout
    (:class:`~fleetctl.mavlink.rtt.RoundTrip`, at most ``timeout``); attempts go on for
    ``(retries + 1) x timeout`` in all, as many as fit. :class:`LinkTimeout` when no ACK comes.
    """
    p = [float(v) for v in params]
    if len(p) > 7:
        raise ValueError("a command has at most 7 parameters")
    p += [0.0] * (7 - len(p))
    name = command_name(command)
    attempts = 0
    async with link.lock(("command", sysid, command)):
        with link.collect("COMMAND_ACK", sysid=sysid, match=lambda m: m.command == command) as inbox:
            deadline = time.monotonic() + (retries + 1) * timeout  # the patience of fixed waits
            attempt = -1
            while (left := deadline - time.monotonic()) > 0:
                attempt += 1
                attempts = attempt + 1
                if frame is None:
                    msg = link.mav.command_long_encode(sysid, compid, command, min(attempt, 255), *p)
                else:
                    msg = link.mav.command_int_encode(sysid, compid, frame, command, 0, 0, *p[:4],
                                                      deg_e7(p[4]), deg_e7(p[5]), p[6])
                link.send(msg, sysid)
                sent = time.monotonic()
                try:
                    ack = await inbox.get(min(link.rtt.timeout(timeout), left))
                except TimeoutError:
                    log.debug("%s: no ACK for %s from %d (attempt %d)", link.url, name, sysid, attempts)
                    continue
                if attempts == 1:
                    link.rtt.add(time.monotonic() - sent)
                while ack.result == M.MAV_RESULT_IN_PROGRESS:
                    try:
                        ack = await inbox.get(progress_timeout)
                    except TimeoutError:
                        raise LinkTimeout(f"system {sysid}: {name} still in progress after "
                                          f"{progress_timeout:g} s") from None
                return CommandAck(sysid, command, ack.result, attempts, getattr(ack, "progress", 0),
                                  getattr(ack, "result_param2", 0))
    raise LinkTimeout(f"system {sysid} did not acknowledge {name} "
                      f"({attempts} attempts in {(retries + 1) * timeout:g} s) on {link.url}")

async def set_message_interval(link: Channel, sysid: int, msgid: int, hz: float, *, compid: int = 1,
                               retries: int = COMMAND_RETRIES) -> CommandAck:
    """MAV_CMD_SET_MESSAGE_INTERVAL: stream ``msgid`` at ``hz`` (0 = the default rate, < 0 = off)."""
    interval = 0.0 if hz == 0 else (-1.0 if hz < 0 else 1e6 / hz)
    return await send_command(link, sysid, M.MAV_CMD_SET_MESSAGE_INTERVAL, (msgid, interval), compid=compid,
                              retries=retries)


__all__ = ["COMMAND_PROGRESS_TIMEOUT", "COMMAND_RETRIES", "COMMAND_TIMEOUT", "send_command",
           "set_message_interval"]
