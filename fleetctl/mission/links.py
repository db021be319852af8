"""The MAVLink links of a mission: which link ("network") each vehicle sits on.

A link is a connection URL (docs/mavlink.md). A carrier's link is its ``connection``; a rover
without a ``connection`` of its own shares its carrier's link; ``connection: sim`` is a link of the
vehicle's own in the embedded simulated fleet (one UDP endpoint per carrier, with the rovers on its
deck). MAVLink system ids are unique per link, not per mission: the controller addresses a vehicle
by its link and system id (its mission id names the pair), so a mission may fly more than 255
vehicles on several links.
"""

from __future__ import annotations

import re
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from fleetctl.mission.model import Mission

SIM = "sim"
TLOG = "traffic.tlog"  # the MAVLink log of a run's first (most often only) link
_FILE_SAFE = re.compile(r"[A-Za-z0-9_-]{1,64}")


def link_key(connection: str | None, owner: str, carrier_link: str | None = None) -> str:
    """The link a vehicle sits on: its ``connection`` URL; ``sim``: the simulated link of ``owner``
    (the vehicle's own id); None (a rover): ``carrier_link``, its carrier's."""
    if connection is None:
        if carrier_link is None:
            raise ValueError(f"vehicle {owner!r}: no connection and no carrier link to share")
        return carrier_link
    return f"{SIM}:{owner}" if connection == SIM else connection


def shown_link(key: str) -> str:
    """A link key as a message shows it: the URL, or ``the simulated link of c1``."""
    if key.startswith(f"{SIM}:"):
        return f"the simulated link of {key.removeprefix(SIM + ':')}"
    return key


def vehicle_links(mission: Mission) -> dict[str, str]:
    """Vehicle id -> the key of its link (:func:`link_key`), every carrier and rover of the mission."""
    out: dict[str, str] = {}
    home: dict[str, str] = {}  # rover id -> its carrier's link
    teams = [(t.carrier, t.rovers) for t in mission.teams] or [(mission.carrier, mission.rovers.ids)]
    for carrier, rovers in teams:
        out[carrier.id] = link_key(carrier.connection, carrier.id)
        home.update(dict.fromkeys(rovers, out[carrier.id]))
    for u in mission.rovers.units:
        out[u.id] = link_key(u.connection, u.id, home.get(u.id, out[mission.carrier.id]))
    return out


def several_links(mission: Mission) -> bool:
    """True when the mission's vehicles sit on more than one link."""
    return len(set(vehicle_links(mission).values())) > 1


def link_tlogs(mission: Mission) -> dict[str, str]:
    """Link key -> the file name of its MAVLink log in the run folder: ``traffic.tlog`` for the first
    link (the only one of most missions), ``traffic-<id>.tlog`` for each further link, after the
    first vehicle on it (``traffic-link<k>.tlog``, the link's ordinal, when that id is no plain
    file name). Each log holds one link's traffic, so system ids that links share stay apart."""
    names: dict[str, str] = {}
    for vid, key in vehicle_links(mission).items():
        if key not in names:
            tail = vid if _FILE_SAFE.fullmatch(vid) else f"link{len(names) + 1}"
            names[key] = TLOG if not names else f"traffic-{tail}.tlog"
    return names


__all__ = ["SIM", "TLOG", "link_key", "link_tlogs", "several_links", "shown_link", "vehicle_links"]
