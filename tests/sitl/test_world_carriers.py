"""The simulated world with several carriers: each rover starts on its own carrier's deck and a
rover touching down by any stopped carrier is loaded on that one (a collection across teams)."""

from __future__ import annotations

from dataclasses import replace

import pytest

from sitl import LOAD_RADIUS, FleetConfig, VehicleSpec, World
from sitl.config import ConfigError

DT = 0.05


def carrier(cid: str, sysid: int, x: float) -> VehicleSpec:
    return VehicleSpec(id=cid, sysid=sysid, role="carrier", max_speed=10.0, accel=5.0,
                       position=(x, 0.0, 0.0), frame="ground")


def rover(rid: str, sysid: int, home: str | None) -> VehicleSpec:
    return VehicleSpec(id=rid, sysid=sysid, role="rover", max_speed=2.0, endurance_range=600.0, carrier=home)


def two_teams() -> World:
    return World(carrier("c1", 1, 0.0), [rover("r1", 11, "c1"), rover("r2", 31, "c2")],
                 [carrier("c2", 2, 50.0)])


def run_until(w: World, cond, limit: float = 600.0) -> None:
    t0 = w.time
    while not cond():
        w.step(DT)
        assert w.time - t0 < limit, "condition never reached"


def test_rovers_start_on_their_own_carriers_deck() -> None:
    w = two_teams()
    assert set(w.carriers) == {"c1", "c2"}
    assert w.rovers["r1"].position == (0.0, 0.0, 0.0) and w.rovers["r2"].position == (50.0, 0.0, 0.0)
    assert w.loaded_rovers("c1") == ["r1"] and w.loaded_rovers("c2") == ["r2"]
    w.carriers["c2"].goto(50.0, 30.0)
    run_until(w, lambda: w.carriers["c2"].arrived)
    assert w.rovers["r2"].position == pytest.approx((50.0, 30.0, 0.0))  # rides with its own carrier
    assert w.rovers["r1"].position == (0.0, 0.0, 0.0)


def test_a_rover_lands_on_the_other_teams_carrier() -> None:
    w = two_teams()
    r = w.rovers["r1"]
    assert r.takeoff(5.0)
    run_until(w, lambda: r.arrived)
    r.goto(50.0 + 0.5 * LOAD_RADIUS, 0.0, 5.0)  # above c2's deck
    run_until(w, lambda: r.arrived)
    r.land()
    run_until(w, lambda: r.on_ground)
    assert r.loaded and r.carrier is w.carriers["c2"]
    assert w.loaded_rovers("c2") == ["r1", "r2"] and w.loaded_rovers("c1") == []
    w.carriers["c2"].goto(80.0, 0.0)  # it now rides with c2
    run_until(w, lambda: w.carriers["c2"].arrived)
    assert r.position == pytest.approx((80.0, 0.0, 0.0))


def test_a_moving_carrier_does_not_load() -> None:
    w = two_teams()
    r = w.rovers["r1"]
    r.takeoff(1.0)
    run_until(w, lambda: r.arrived)
    w.carriers["c1"].goto(500.0, 0.0)  # drives off under it
    run_until(w, lambda: w.carriers["c1"].speed > 5.0)
    r.goto(w.carriers["c1"].position[0], 0.0, 0.1)
    r.land()
    run_until(w, lambda: r.on_ground)
    assert not r.loaded


def test_config_checks_a_rovers_carrier() -> None:
    with pytest.raises(ConfigError, match="no carrier 'c9'"):
        FleetConfig(origin=(47.0, 8.0, 400.0), carrier=carrier("c1", 1, 0.0), rovers=[rover("r1", 11, "c9")])
    radio = "udp://127.0.0.1:0"
    with pytest.raises(ConfigError, match="sysid 1 is used twice"):  # on one link
        FleetConfig(origin=(47.0, 8.0, 400.0), carrier=replace(carrier("c1", 1, 0.0), connection=radio),
                    rovers=[], more_carriers=[replace(carrier("c2", 1, 5.0), connection=radio)])
    with pytest.raises(ConfigError, match="fleetctl sim"):
        FleetConfig.from_mission_dict({"carriers": []})


def test_system_ids_are_unique_per_link() -> None:
    """Each simulated carrier is a link of its own with its deck's rovers: the same system ids on
    two links are two vehicles, each served on its own endpoint."""
    cfg = FleetConfig(origin=(47.0, 8.0, 400.0), carrier=carrier("c1", 1, 0.0),
                      rovers=[rover("r1", 11, "c1"), rover("r2", 11, "c2")],
                      more_carriers=[carrier("c2", 1, 50.0)])
    assert cfg.link_groups() == {"sim#c1": ["c1", "r1"], "sim#c2": ["c2", "r2"]}
    radio = "udp://127.0.0.1:0"
    with pytest.raises(ConfigError, match="sysid 11 is used twice on link 'sim#c1'"):
        FleetConfig(origin=(47.0, 8.0, 400.0), carrier=carrier("c1", 1, 0.0),
                    rovers=[rover("r1", 11, "c1"), rover("r2", 11, "c1"), replace(rover("r3", 11, "c1"),
                                                                                  connection=radio)])
