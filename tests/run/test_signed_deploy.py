"""A signed deployment under attack: spoofed unsigned HEARTBEAT, COMMAND_ACK,
GLOBAL_POSITION_INT and MISSION_ITEM_REACHED from another local socket change nothing, and the
summary counts them."""

from __future__ import annotations

import asyncio
import math
from pathlib import Path
from typing import Any

import pytest
from pymavlink.dialects.v20 import ardupilotmega as M

from fleetctl.geo import Origin, enu_to_geodetic
from fleetctl.mavlink.fleet import Fleet
from fleetctl.run.flight import execute
from fleetctl.run.sim import sim_mission_dict
from fleetctl.run.state import Event, FleetState
from fleetctl.views.view import View
from sitl import FleetConfig, SimFleet
from tests.mavlink.test_signing import ENV, KEY_HEX, Spoofer, armed_heartbeat, codec, signed_dict
from tests.run.ctl_helpers import mission_from


class Attacker(View):
    """Once the carrier starts, floods the controller's link with unsigned lies."""

    def __init__(self, mission: Any) -> None:
        self.mission = mission
        self.fleet: Fleet | None = None
        self.task: asyncio.Task[None] | None = None

    def start(self, state: FleetState, fleet: Fleet | None) -> None:
        if fleet is not None:
            self.fleet = fleet
            state.add_listener(self._on)

    def _on(self, ev: Event) -> None:
        if ev.kind == "carrier_started" and self.task is None:
            self.task = asyncio.ensure_future(self._attack())

    async def _attack(self) -> None:
        assert self.fleet is not None
        link = next(iter(self.fleet.links.values()))
        spoof = Spoofer(link.local_port or 0)
        o = self.mission.origin
        origin = Origin(o.lat, o.lon, o.alt)
        try:
            for n in range(40):
                for i, t in enumerate(self.mission.tasks):  # every rover "at" a task
                    lat, lon, alt = enu_to_geodetic(*t.position, origin)
                    mav = codec(11 + i)
                    spoof.send(bytes(mav.global_position_int_encode(
                        1000 + n * 100, int(lat * 1e7), int(lon * 1e7), int(alt * 1000),
                        int(t.position[2] * 1000), 0, 0, 0, 0).pack(mav)))
                carrier = codec(1)
                spoof.send(armed_heartbeat(carrier))
                for seq in range(8):  # "arrived" at every stop
                    spoof.send(bytes(carrier.mission_item_reached_encode(seq).pack(carrier)))
                ack = carrier.command_ack_encode(M.MAV_CMD_DO_SET_MISSION_CURRENT, M.MAV_RESULT_ACCEPTED,
                                                 0, 0, 255, 190)
                spoof.send(bytes(ack.pack(carrier)))
                await asyncio.sleep(0.05)
        finally:
            spoof.close()

    async def stop(self) -> None:
        if self.task is not None:
            self.task.cancel()


async def test_spoofing_a_signed_deployment_changes_nothing(tmp_path: Path,
                                                             monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(ENV, KEY_HEX)
    d = signed_dict(rovers=2)
    mission = mission_from(d, tmp_path)
    cfg = FleetConfig.from_mission_dict(sim_mission_dict(mission), speedup=10.0)
    attacker = Attacker(mission)
    async with SimFleet(cfg) as sim:
        out = await asyncio.wait_for(execute(mission, "deploy", sim=sim, runs_dir=tmp_path / "runs",
                                             view=attacker), 120)
        where = {rid: sim.rover(rid).position for rid in ("r1", "r2")}
    s = out.summary
    assert attacker.task is not None and attacker.task.done()
    assert out.exit_code == 0, s
    for task, rid in s["assignment"].items():  # really there, in the simulated world
        t = next(x for x in mission.tasks if x.id == task)
        assert math.dist(where[rid], t.position) < 1.5, (task, rid, where[rid])
    assert s["link"]["rejected_unsigned"] >= 100, s["link"]
    assert s["link"]["rejected_bad_signature"] == 0
