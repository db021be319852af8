"""The MAVLink mission protocol on a link: :func:`upload_mission` (MISSION_COUNT → MISSION_REQUEST_INT
→ MISSION_ITEM_INT → MISSION_ACK, the vehicle driving the transfer), :func:`download_mission` and
:func:`clear_mission`, with the spec's 1.5 s timeout, 5 retries and re-requested items. One
transfer per vehicle at a time."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from pymavlink.dialects.v20 import ardupilotmega as M

from fleetctl.mavlink.errors import LinkTimeout, MissionRejected
from fleetctl.mavlink.expectations import Inbox
from fleetctl.mavlink.messages import MissionItem

if TYPE_CHECKING:
    from fleetctl.mavlink.channel import Channel

log = logging.getLogger(__name__)

MISSION_TIMEOUT = 1.5  # s, MAVLink mission protocol default
MISSION_ITEM_TIMEOUT = 0.25  # s, first wait for one item; doubles on each retry up to MISSION_TIMEOUT
MISSION_RETRIES = 5
EARLY_RESENDS = 8  # resends in a row at the retransmission timeout before the wait starts doubling: with
# 40 % loss each way an exchange fails 64 % of the time, so 3 resends in a row failed 17 % of the time
# and the wait then doubled up to the 1.5 s timeout (the long tail of a lossy upload: 3 s for 3 items);
# 8 fail 2.8 % of the time. A vehicle that does not answer costs 8 retransmission timeouts more


def _mission_match(mission_type: int) -> Callable[[Any], bool]:
    return lambda m: getattr(m, "mission_type", 0) == mission_type

async def upload_mission(
    link: Channel, sysid: int, items: list[MissionItem], *, compid: int = 1, mission_type: int = 0,
    timeout: float = MISSION_TIMEOUT, item_timeout: float = MISSION_ITEM_TIMEOUT,
    retries: int = MISSION_RETRIES,
) -> None:
    """Upload ``items`` (MISSION_COUNT → MISSION_REQUEST_INT → MISSION_ITEM_INT → MISSION_ACK).

    The vehicle drives the transfer: whatever item it requests is sent, so re-requested and
    out-of-order items are served. Without an answer the last message is resent after the link's
    retransmission timeout (:class:`~fleetctl.mavlink.rtt.RoundTrip`; before a round trip is known,
    ``timeout`` for the COUNT and ``item_timeout`` or three COUNT round trips for an item), the
    wait doubling up to ``timeout`` after :data:`EARLY_RESENDS` resends in a row, at most
    ``retries`` times in a row after waits of the full ``timeout`` (the shorter early resends come
    on top). Every exchange answered at its first send is a round trip sample of the link; a
    MAV_MISSION_INVALID_SEQUENCE ACK during the transfer answers a resent item that crossed its
    request and is passed over. :class:`MissionRejected` on another error ACK (the vehicle keeps its
    previous mission), :class:`LinkTimeout` after the retries (the transfer is cancelled).
    """
    n = len(items)
    types = ("MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK")
    async with link.lock(("mission", sysid)):
        with link.collect(types, sysid=sysid, match=_mission_match(mission_type)) as inbox:
            count_msg = link.mav.mission_count_encode(sysid, compid, n, mission_type)
            link.send(count_msg, sysid)
            t0 = time.monotonic()
            last: Any = count_msg
            started = False
            wait = link.rtt.timeout(timeout)  # the link's retransmission timeout, once known
            first = item_timeout
            left = retries
            served = 0
            resent = 0  # resends of the last message in a row
            while True:
                try:
                    m = await inbox.get(wait)
                except TimeoutError:
                    if wait >= timeout:  # early resends (a wait shorter than the timeout) are extra
                        if left == 0:
                            cancel = M.MAV_MISSION_OPERATION_CANCELLED
                            link.send(link.mav.mission_ack_encode(sysid, compid, cancel, mission_type), sysid)
                            raise LinkTimeout(f"system {sysid}: mission upload timed out after {retries} "
                                              f"retries ({served} of {n} items sent) on {link.url}") from None
                        left -= 1
                    link.send(last, sysid)
                    t0 = time.monotonic()  # the round trip is measured from the last send
                    resent += 1
                    if resent > EARLY_RESENDS:
                        wait = min(wait * 2, timeout)  # backing off up to the protocol timeout
                    continue
                if not resent and m.get_type() != "MISSION_ACK":
                    link.rtt.add(time.monotonic() - t0)  # answered at its first send: a round trip
                if m.get_type() == "MISSION_ACK":
                    if m.type == M.MAV_MISSION_ACCEPTED:
                        if started or n == 0:
                            log.info("%s: mission of %d items uploaded to %d", link.url, n, sysid)
                            return
                        continue  # a stale ACK of an earlier transfer
                    if started and m.type == M.MAV_MISSION_INVALID_SEQUENCE:
                        continue  # our resend of an item crossed its request (ArduPilot answers so)
                    raise MissionRejected(sysid, "upload", m.type)
                seq = m.seq
                if not 0 <= seq < n:
                    log.warning("%s: system %d requested item %d of %d; ignored", link.url, sysid, seq, n)
                    continue
                if not started:
                    started = True
                    first = max(item_timeout, 3.0 * (time.monotonic() - t0))  # until a round trip is known
                it = items[seq]
                # MISSION_ITEM_INT also answers a legacy MISSION_REQUEST: ArduPilot asks that way
                # and rejects a float MISSION_ITEM in an _INT frame (MAV_MISSION_INVALID_PARAM4)
                last = link.mav.mission_item_int_encode(
                    sysid, compid, seq, it.frame, it.command, it.current, it.autocontinue, it.param1,
                    it.param2, it.param3, it.param4, it.x, it.y, it.z, mission_type)
                link.send(last, sysid)
                served = max(served, seq + 1)
                t0 = time.monotonic()
                left, resent = retries, 0
                wait = link.rtt.timeout(first if link.rtt.srtt is None else timeout)

async def download_mission(
    link: Channel, sysid: int, *, compid: int = 1, mission_type: int = 0, timeout: float = MISSION_TIMEOUT,
    item_timeout: float = MISSION_ITEM_TIMEOUT, retries: int = MISSION_RETRIES,
) -> list[MissionItem]:
    """Download the vehicle's mission (MISSION_REQUEST_LIST → COUNT → REQUEST_INT → ITEM_INT → ACK).
    On ArduPilot item 0 is home."""
    types = ("MISSION_COUNT", "MISSION_ITEM_INT", "MISSION_ITEM", "MISSION_ACK")
    async with link.lock(("mission", sysid)):
        with link.collect(types, sysid=sysid, match=_mission_match(mission_type)) as inbox:
            count_msg = await _exchange(
                link, inbox, link.mav.mission_request_list_encode(sysid, compid, mission_type), sysid,
                lambda m: m.get_type() == "MISSION_COUNT", link.rtt.timeout(timeout), timeout, retries,
                "download")
            n = count_msg.count
            first = max(item_timeout, 3.0 * link.mission_rtt)
            base = link.rtt.timeout(first if link.rtt.srtt is None else timeout)
            items: list[MissionItem] = []
            for seq in range(n):
                def is_item(m: Any, seq: int = seq) -> bool:
                    return m.get_type() in ("MISSION_ITEM_INT", "MISSION_ITEM") and m.seq == seq

                m = await _exchange(
                    link, inbox, link.mav.mission_request_int_encode(sysid, compid, seq, mission_type), sysid,
                    is_item, base, timeout, retries, "download")
                items.append(MissionItem.from_msg(m))
            if n:
                ok = M.MAV_MISSION_ACCEPTED
                link.send(link.mav.mission_ack_encode(sysid, compid, ok, mission_type), sysid)
            return items

async def clear_mission(link: Channel, sysid: int, *, compid: int = 1, mission_type: int = 0,
                        timeout: float = MISSION_TIMEOUT, retries: int = MISSION_RETRIES) -> None:
    """MISSION_CLEAR_ALL → MISSION_ACK."""
    async with link.lock(("mission", sysid)):
        with link.collect("MISSION_ACK", sysid=sysid, match=_mission_match(mission_type)) as inbox:
            await _exchange(link, inbox, link.mav.mission_clear_all_encode(sysid, compid, mission_type),
                                 sysid, lambda m: True, link.rtt.timeout(timeout), timeout, retries, "clear")

async def _exchange(link: Channel, inbox: Inbox, msg: Any, sysid: int, accept: Callable[[Any], bool],
                    first_wait: float, max_wait: float, retries: int, operation: str) -> Any:
    """Send ``msg`` until a message passing ``accept`` arrives; an error MISSION_ACK is final. The
    wait doubles from ``first_wait`` to ``max_wait``; ``retries`` counts the resends after a
    ``max_wait`` one (the shorter early ones come on top)."""
    wait, left, attempt = first_wait, retries + 1, 0
    while left > 0:
        if wait >= max_wait:
            left -= 1
        if attempt:
            log.debug("%s: resending %s to %d (retry %d)", link.url, msg.get_type(), sysid, attempt)
        attempt += 1
        link.send(msg, sysid)
        sent = time.monotonic()
        deadline = sent + wait
        while (remaining := deadline - time.monotonic()) > 0:
            try:
                m = await inbox.get(remaining)
            except TimeoutError:
                break
            if m.get_type() == "MISSION_ACK" and m.type != M.MAV_MISSION_ACCEPTED:
                raise MissionRejected(sysid, operation, m.type)
            if accept(m):
                link.mission_rtt = time.monotonic() - sent
                if attempt == 1:
                    link.rtt.add(link.mission_rtt)  # answered at its first send: a round trip
                return m
        wait = min(wait * 2, max_wait)
    raise LinkTimeout(f"system {sysid}: mission {operation} timed out ({msg.get_type()} unanswered "
                      f"after {retries} retries) on {link.url}")


__all__ = ["EARLY_RESENDS", "MISSION_ITEM_TIMEOUT", "MISSION_RETRIES", "MISSION_TIMEOUT", "clear_mission",
           "download_mission", "upload_mission"]
