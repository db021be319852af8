"""``fleetctl keys provision``: give every vehicle of a mission the fleet's signing key with
SETUP_SIGNING (MAVLink 2 spec), then check that each one answers signed traffic.

Per link: open it signing with the key but accepting anything (a vehicle without a key sends
unsigned telemetry and accepts signed messages without checking them; one that already has this
key accepts them too), wait for each vehicle's heartbeat, refuse an armed vehicle (as autopilots
do), send SETUP_SIGNING a few times (it has no acknowledgement), then switch the link to verifying
and require a correctly signed COMMAND_ACK to a REQUEST_MESSAGE. SETUP_SIGNING carries the key in
clear: provision over a trusted link (USB, a wired or local network), not over the air.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from pymavlink.dialects.v20 import ardupilotmega as M

from fleetctl.mavlink.link import Link, LinkError
from fleetctl.mavlink.signing import SigningKey
from fleetctl.mission.teams import mission_teams

if TYPE_CHECKING:
    from fleetctl.mission import Mission

log = logging.getLogger(__name__)

SETUP_REPEAT = 3  # SETUP_SIGNING has no reply: sent this many times, 0.2 s apart


@dataclass(frozen=True)
class ProvisionResult:
    vehicle: str
    sysid: int
    url: str
    ok: bool
    detail: str

    def line(self) -> str:
        status = "ok    " if self.ok else "FAILED"
        return f"{status} {self.vehicle:<12} sysid {self.sysid:<4} {self.url}: {self.detail}"


async def provision(mission: Mission, key: SigningKey, urls: Mapping[str, str], *, timeout: float = 5.0,
                    signing_state: str | Path | None | bool = None) -> list[ProvisionResult]:
    """Provision every vehicle in ``urls`` (vehicle id -> URL); one result per vehicle."""
    sysids = {t.carrier.id: t.carrier.sysid for t in mission_teams(mission)}
    sysids |= {u.id: u.sysid for u in mission.rovers.units}
    by_url: dict[str, list[str]] = {}
    for vid, url in urls.items():
        by_url.setdefault(url, []).append(vid)
    results: dict[str, ProvisionResult] = {}

    async def one_link(link_id: int, url: str, vids: list[str]) -> None:
        link = Link(url)
        try:
            await link.open(timeout=min(timeout, 5.0))
        except LinkError as exc:
            for vid in vids:
                results[vid] = ProvisionResult(vid, sysids[vid], url, False, str(exc))
            return
        try:
            link.enable_signing(key, link_id=link_id, state=signing_state, verify=False)
            await asyncio.gather(*(one_vehicle(link, url, vid, sysids[vid]) for vid in vids))
        finally:
            await link.close()

    async def one_vehicle(link: Link, url: str, vid: str, sysid: int) -> None:
        def result(ok: bool, detail: str) -> None:
            results[vid] = ProvisionResult(vid, sysid, url, ok, detail)

        def is_autopilot(m: object) -> bool:
            return getattr(m, "type", None) != M.MAV_TYPE_GCS and getattr(m, "autopilot", None) != \
                M.MAV_AUTOPILOT_INVALID

        try:
            hb = await asyncio.wait_for(link.expect("HEARTBEAT", sysid=sysid, match=is_autopilot), timeout)
        except TimeoutError:
            result(False, f"no heartbeat within {timeout:g} s")
            return
        if hb.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED:
            result(False, "refused: the vehicle is armed (disarm it, then provision again)")
            return
        compid = hb.get_srcComponent()
        for k in range(SETUP_REPEAT):
            assert link.signer is not None
            link.send(link.mav.setup_signing_encode(sysid, compid, list(key.secret), link.signer.timestamp),
                      sysid)
            if k + 1 < SETUP_REPEAT:
                await asyncio.sleep(0.2)
        result(False, "pending")

    await asyncio.gather(*(one_link(k, url, vids) for k, (url, vids) in enumerate(by_url.items())))
    # second pass: every link verifying, each provisioned vehicle must answer signed
    pending = {vid: r for vid, r in results.items() if r.detail == "pending"}
    if pending:
        await _verify(pending, key, results, timeout, signing_state)
    return [results[vid] for vid in urls]


async def _verify(pending: Mapping[str, ProvisionResult], key: SigningKey,
                  results: dict[str, ProvisionResult], timeout: float,
                  signing_state: str | Path | None | bool) -> None:
    by_url: dict[str, list[ProvisionResult]] = {}
    for r in pending.values():
        by_url.setdefault(r.url, []).append(r)

    async def check(link: Link, r: ProvisionResult) -> None:
        try:
            await asyncio.wait_for(link.expect("HEARTBEAT", sysid=r.sysid), timeout)
            ack = await link.command(r.sysid, M.MAV_CMD_REQUEST_MESSAGE,
                                     (M.MAVLINK_MSG_ID_AUTOPILOT_VERSION,), timeout=0.5, retries=3)
        except (TimeoutError, LinkError):
            why = "no signed answer after SETUP_SIGNING (does it support signing? another key already set?)"
            results[r.vehicle] = ProvisionResult(r.vehicle, r.sysid, r.url, False, why)
            return
        results[r.vehicle] = ProvisionResult(r.vehicle, r.sysid, r.url, True,
                                             f"key {key.fingerprint} set; answers signed traffic "
                                             f"({ack.result_name.removeprefix('MAV_RESULT_')})")

    async def one_link(link_id: int, url: str, rs: list[ProvisionResult]) -> None:
        link = Link(url, signing_key=key, link_id=link_id, signing_state=signing_state)
        try:
            await link.open(timeout=min(timeout, 5.0))
            await asyncio.gather(*(check(link, r) for r in rs))
        except LinkError as exc:
            for r in rs:
                results[r.vehicle] = ProvisionResult(r.vehicle, r.sysid, r.url, False, str(exc))
        finally:
            await link.close()

    await asyncio.gather(*(one_link(k, url, rs) for k, (url, rs) in enumerate(by_url.items())))


__all__ = ["ProvisionResult", "provision"]
