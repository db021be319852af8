"""The mission's fleet: every vehicle of a mission on its links (:func:`connect_fleet`)."""

from __future__ import annotations

import asyncio
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fleetctl.mavlink.link import Link, LinkError
from fleetctl.mavlink.signing import REJECTION_KEYS, SigningKey, SigningKeyError
from fleetctl.mavlink.vehicle import DEFAULT_POSITION_HZ, Listener, Vehicle, VehicleEvent, put_event
from fleetctl.mission.links import vehicle_links

if TYPE_CHECKING:
    from fleetctl.mission import Mission

Tap = Callable[[str, float, bytes], None]


CONNECT_HINT = "check the URL, the system id and that the vehicle is powered"


class FleetConnectError(Exception):
    """Some vehicles of the mission did not answer; ``missing`` maps vehicle id -> its URL."""

    def __init__(self, missing: Mapping[str, str], reasons: Mapping[str, str],
                 lines: list[str] | None = None) -> None:
        self.missing = dict(missing)
        self.reasons = dict(reasons)
        lines = lines or [f"{vid}: {reasons.get(vid, 'no answer')} on {url}" for vid, url in missing.items()]
        super().__init__(f"{len(lines)} vehicle(s) did not answer ({CONNECT_HINT}):\n  " + "\n  ".join(lines))


class Fleet:
    """The mission's vehicles on their links. Close it (or use ``async with``) to close the links."""

    def __init__(self, carrier_id: str, vehicles: dict[str, Vehicle], links: dict[str, Link],
                 urls: dict[str, str], errors: dict[str, str], other_carriers: tuple[str, ...] = ()) -> None:
        self.carrier_id = carrier_id
        self.vehicles = vehicles  # id -> Vehicle (carrier first, then rovers in mission order)
        self.links = links  # url -> open Link
        self.urls = urls  # id -> url
        self.errors = errors  # id -> why it is not connected (link errors, no heartbeat)
        self.left_out: dict[str, str] = {}  # rover id -> why it does not fly (failed preflight)
        self.silence: dict[str, str] = {}  # id -> what its link heard instead of its heartbeat
        self.other_carriers = other_carriers  # several teams: the carriers after the first (no rovers)

    @property
    def carrier(self) -> Vehicle:
        return self.vehicles[self.carrier_id]

    @property
    def carrier_ids(self) -> tuple[str, ...]:
        """Every carrier of the fleet (several teams: the first, then the others)."""
        return (self.carrier_id, *self.other_carriers)

    @property
    def rovers(self) -> dict[str, Vehicle]:
        """The rovers that fly: every rover of the mission but those :meth:`leave_out` removed."""
        return {k: v for k, v in self.vehicles.items()
                if k != self.carrier_id and k not in self.left_out and k not in self.other_carriers}

    def team(self, carrier_id: str, rover_ids: tuple[str, ...] | list[str]) -> FleetView:
        """One team's part of this fleet: that carrier and those rovers, on the same vehicle proxies
        and links (a view: closing it closes nothing; the whole fleet owns them)."""
        ids = [carrier_id, *rover_ids]
        unknown = [vid for vid in ids if vid not in self.vehicles]
        if unknown:
            raise KeyError(f"no vehicle {unknown[0]!r} in the fleet")
        urls = {vid: self.urls[vid] for vid in ids}
        links = {url: self.links[url] for url in dict.fromkeys(urls.values()) if url in self.links}
        errors = {vid: why for vid, why in self.errors.items() if vid in urls}
        view = FleetView(carrier_id, {vid: self.vehicles[vid] for vid in ids}, links, urls, errors)
        view.silence = {vid: why for vid, why in self.silence.items() if vid in urls}
        return view

    def leave_out(self, rover_id: str, why: str) -> None:
        """Keep a (connected) rover out of the run: it stays in ``vehicles`` but not in ``rovers``."""
        if rover_id == self.carrier_id:
            raise ValueError("the carrier cannot be left out")
        self.left_out[rover_id] = why

    def failure_line(self, vid: str) -> str:
        """One short line on why a vehicle is not connected: ``r3 (sysid 13): no heartbeat within
        10 s on udp://127.0.0.1:14550; no MAVLink traffic at all on this link: …`` (what its link
        heard instead: :meth:`fleetctl.mavlink.link.Link.why_silent`)."""
        why = self.errors.get(vid, "no heartbeat")
        heard = self.silence.get(vid)
        line = f"{vid} (sysid {self.vehicles[vid].sysid}): {why} on {self.urls[vid]}"
        return f"{line}; {heard}" if heard else line

    def missing(self) -> dict[str, str]:
        """id -> URL of every vehicle never heard from."""
        return {vid: self.urls[vid] for vid, v in self.vehicles.items() if not v.connected}

    def add_listener(self, listener: Listener) -> Callable[[], None]:
        """``listener(event)`` for every vehicle's events; returns the remover."""
        return _all_of([v.add_listener(listener) for v in self.vehicles.values()])

    def event_queue(self, maxsize: int = 0) -> asyncio.Queue[VehicleEvent]:
        q: asyncio.Queue[VehicleEvent] = asyncio.Queue(maxsize)
        self.add_listener(lambda ev: put_event(q, ev))
        return q

    def link_rejections(self) -> dict[str, int]:
        """What the links and vehicle proxies refused, summed over the fleet (for the run summary's
        ``"link"`` section): ``rejected_unsigned``, ``rejected_bad_signature``, ``rejected_replay``
        (signing), ``route_conflicts`` (a known system id from another address), and from the
        proxies ``positions_held`` (implausible position jumps not applied) and
        ``item_reached_rejected`` (MISSION_ITEM_REACHED far from the item)."""
        out = dict.fromkeys(REJECTION_KEYS.values(), 0)
        out["route_conflicts"] = 0
        for link in self.links.values():
            for k, n in link.rejected.items():
                out[k] = out.get(k, 0) + n
            out["route_conflicts"] += link.route_conflicts
        for k in ("positions_held", "item_reached_rejected"):
            out[k] = sum(getattr(v, k, 0) for v in self.vehicles.values())
        return out

    @property
    def signing(self) -> bool:
        """True when every link signs (the mission's ``links.signing``)."""
        return bool(self.links) and all(link.signing for link in self.links.values())

    def on_route_conflict(self, callback: Callable[[str | None, int, Any, Any], None]) -> None:
        """``callback(vehicle_id or None, sysid, old_addr, new_addr)`` on every link's route conflict
        (e.g. to journal it)."""
        ids = {(self.urls[vid], v.sysid): vid for vid, v in self.vehicles.items()}
        for url, link in self.links.items():
            def cb(sysid: int, old: Any, new: Any, url: str = url) -> None:
                callback(ids.get((url, sysid)), sysid, old, new)

            link.on_route_conflict = cb

    def add_tap(self, tap: Callable[[str, float, bytes], None]) -> Callable[[], None]:
        """Tap every link (e.g. a :class:`fleetctl.mavlink.tlog.TlogWriter`); returns the remover."""
        return _all_of([link.add_tap(tap) for link in self.links.values()])

    async def close(self) -> None:
        for v in self.vehicles.values():
            v.close()
        await asyncio.gather(*(link.close() for link in self.links.values()))

    async def __aenter__(self) -> Fleet:
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()


class FleetView(Fleet):
    """A team's vehicles of a larger :class:`Fleet` (:meth:`Fleet.team`): ``close`` leaves the
    shared vehicles and links open."""

    async def close(self) -> None:
        return None


def _all_of(removers: list[Callable[[], None]]) -> Callable[[], None]:
    def remove() -> None:
        for r in removers:
            r()

    return remove


def fleet_urls(mission: Mission, endpoints: Mapping[str, str] | None = None) -> dict[str, str]:
    """vehicle id -> connection URL: ``endpoints`` first (e.g. ``SimFleet.endpoints``), else the
    mission's connection; a rover without one shares the carrier's. ``sim`` without endpoints is
    an error (start the simulated fleet and pass its endpoints)."""
    eps = dict(endpoints or {})
    urls: dict[str, str] = {}
    home: dict[str, str] = {}  # rover -> its carrier's url
    for c, rovers in _teams(mission):
        urls[c.id] = eps.get(c.id, c.connection)
        home.update(dict.fromkeys(rovers, urls[c.id]))
    for u in mission.rovers.units:
        urls[u.id] = eps.get(u.id) or u.connection or home.get(u.id, urls[mission.carrier.id])
    sim = [vid for vid, url in urls.items() if url == "sim"]
    if sim:
        raise LinkError(f"connection 'sim' of {', '.join(sim)}: start the simulated fleet "
                        "(sitl.SimFleet) and pass its endpoints, or give a real connection URL")
    return urls


def _link_taps(mission: Mission, urls: Mapping[str, str],
               tap: Tap | Mapping[str, Tap] | None) -> dict[str, Tap]:
    """URL -> the tap of that link (``tap`` for every link, or ``tap[link key]``)."""
    if tap is None:
        return {}
    if not isinstance(tap, Mapping):
        return dict.fromkeys(urls.values(), tap)
    keys = vehicle_links(mission)
    return {url: tap[keys[vid]] for vid, url in urls.items() if keys.get(vid) in tap}


async def connect_fleet(
    mission: Mission, endpoints: Mapping[str, str] | None = None, *, timeout: float = 10.0,
    require_all: bool = True, gcs_sysid: int = 255, configure_streams: bool = True,
    position_hz: float = DEFAULT_POSITION_HZ, tap: Tap | Mapping[str, Tap] | None = None,
    signing_key: SigningKey | None = None, signing_state: str | Path | None | bool = None,
) -> Fleet:
    """Open the links the mission names and wait up to ``timeout`` s for every vehicle's first
    heartbeat (then set its message rates).

    ``endpoints``: vehicle id -> URL overriding the mission (needed for ``connection: sim``:
    pass ``SimFleet.endpoints``). With ``require_all`` a missing vehicle raises
    :class:`FleetConnectError` naming each one and its URL (and closes everything); otherwise the
    fleet is returned with ``fleet.missing()``/``fleet.errors`` filled in. ``tap`` sees every
    datagram from before the first heartbeat on (the ``.tlog`` records the connect phase): one tap for
    every link, or one per link keyed by link (:func:`fleetctl.mission.links.vehicle_links`).

    Signing: with the mission's ``links.signing`` (or ``signing_key``) every link signs with the
    key read from the environment variable ``links.signing.key_env`` (:class:`LinkError` naming it
    when unset or malformed), each link with its own ``link_id``; the outgoing timestamp is kept in
    ``signing_state`` (a file or a directory such as the run folder; None = the user's
    ``~/.local/state/fleetctl``). Links refuse route takeovers for ``links.heartbeat_timeout``.
    """
    urls = fleet_urls(mission, endpoints)
    origin = mission.origin
    hb_timeout = mission.links.heartbeat_timeout
    carriers = [c for c, _ in _teams(mission)]
    sysids = {c.id: c.sysid for c in carriers} | {u.id: u.sysid for u in mission.rovers.units}
    links: dict[str, Link] = {}
    errors: dict[str, str] = {}
    key = signing_key
    if key is None and mission.links.signing is not None:
        try:
            key = SigningKey.from_env(mission.links.signing.key_env)
        except SigningKeyError as exc:
            raise LinkError(str(exc)) from None
    all_links = {url: Link(url, sysid=gcs_sysid, signing_key=key, link_id=k, signing_state=signing_state,
                           route_timeout=hb_timeout)
                 for k, url in enumerate(dict.fromkeys(urls.values()))}  # URL errors raise
    taps = _link_taps(mission, urls, tap)
    for url, link in all_links.items():
        if url in taps:
            link.add_tap(taps[url])
        try:
            await link.open(timeout=min(timeout, 5.0))
            links[url] = link
        except LinkError as exc:
            for vid, u in urls.items():
                if u == url:
                    errors[vid] = str(exc).removeprefix(f"connection {url!r}: ")
    # a vehicle whose link failed to open keeps a proxy on the unopened link: it is reported, never heard
    # plausibility bound: a rover rides the carrier, so it may move at the faster of the two speeds
    speeds = {c.id: c.max_speed for c in carriers}
    rover_speed = max(mission.rovers.max_speed, *(c.max_speed for c in carriers))
    vehicles = {vid: Vehicle(all_links[url], sysids[vid], name=vid, origin=origin,
                             heartbeat_timeout=hb_timeout, max_speed=speeds.get(vid, rover_speed))
                for vid, url in urls.items()}
    fleet = Fleet(mission.carrier.id, vehicles, links, urls, errors, tuple(c.id for c in carriers[1:]))

    async def first_heartbeat(vid: str, v: Vehicle) -> None:
        if vid in errors:
            return
        try:
            await v.wait_heartbeat(timeout)
        except TimeoutError:
            errors[vid] = f"no heartbeat within {timeout:g} s"
            on_link = (sysids[other] for other, url in urls.items() if url == urls[vid])
            fleet.silence[vid] = v.link.why_silent(v.sysid, on_link)

    await asyncio.gather(*(first_heartbeat(vid, v) for vid, v in vehicles.items()))
    missing = fleet.missing()
    if missing and require_all:
        await fleet.close()
        raise FleetConnectError(missing, errors, [fleet.failure_line(vid) for vid in missing])
    if configure_streams:
        await asyncio.gather(*(v.configure_streams(position_hz) for v in vehicles.values() if v.connected))
    return fleet




def _teams(mission: Mission) -> list[tuple[Any, tuple[str, ...]]]:
    """(carrier, its rover ids) of every team (one team: the carrier and every rover)."""
    if mission.teams:
        return [(t.carrier, t.rovers) for t in mission.teams]
    return [(mission.carrier, tuple(u.id for u in mission.rovers.units))]


__all__ = ["CONNECT_HINT", "Fleet", "FleetConnectError", "FleetView", "Tap", "connect_fleet", "fleet_urls"]
