"""firmware_speeds: the mission's speeds as autopilot parameters (clamped), the handling the plan
takes from the firmware, the mission keys, and docs/autopilots.md kept true."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import ardupilotmega as M

from fleetctl.mavlink.autopilots import ArduPilot
from fleetctl.mavlink.autopilots import ardupilot as apm
from fleetctl.mavlink.vehicle import HOME_ALT_TOLERANCE
from fleetctl.mission import MissionError
from fleetctl.mission.flight import MEET_HEIGHT, TAKEOFF_HEIGHT
from fleetctl.run.collect import RETARGET_OFFSET
from fleetctl.run.firmware_speeds import fitted_handling, quantities
from tests.run.ctl_helpers import mission_dict, mission_from

DOC = Path(__file__).resolve().parents[2] / "docs" / "autopilots.md"


def test_copter_parameters_follow_the_mission_within_the_firmware_range(tmp_path: Path) -> None:
    d = mission_dict(carrier_connection="udpin://127.0.0.1:14599")
    d["rovers"].update(max_speed=5.0, accel=2.5, climb_rate=3.0, land_speed=4.0)
    m = mission_from(d, tmp_path)
    values = ArduPilot().speed_values(quantities(m, carrier=False))
    # LAND_SPEED at most 2 m/s; a leg's descent at the time model's max_speed, not the landing speed
    assert values == {"WPNAV_SPEED": 500.0, "WPNAV_ACCEL": 250.0, "WPNAV_ACCEL_Z": 250.0,
                      "WPNAV_SPEED_UP": 300.0, "WPNAV_SPEED_DN": 500.0, "LAND_SPEED": 200.0}
    rover = ArduPilot(M.MAV_TYPE_GROUND_ROVER).speed_values(quantities(m, carrier=True))
    assert rover["WP_SPEED"] == rover["CRUISE_SPEED"] == m.carrier.max_speed


def test_the_plan_takes_the_copters_measured_handling_where_the_file_is_silent(tmp_path: Path) -> None:
    d = mission_dict(carrier_connection="udpin://127.0.0.1:14599")
    d["rovers"].update(max_speed=5.0, accel=2.5, land_speed=1.0)
    m = mission_from(d, tmp_path)
    fitted = fitted_handling(m, [ArduPilot()])
    assert fitted is not None
    r = fitted.rovers
    assert r.takeoff_time == pytest.approx(TAKEOFF_HEIGHT / 5.0 + apm.COPTER_TAKEOFF_OVERHEAD)
    # the carrier's load_time (2 s, from the touch-down) covers most of the auto-disarm
    disarm_left = max(0.0, apm.COPTER_DISARM_DELAY - m.carrier.load_time)
    assert r.land_time == pytest.approx(MEET_HEIGHT / 1.0 + apm.COPTER_TOUCHDOWN_OVERHEAD + disarm_left)
    d["carrier"]["deck_height"] = 0.5  # the descent onto a deck 0.5 m up: 2.5 m
    deck = fitted_handling(mission_from(d, tmp_path), [ArduPilot()])
    assert deck is not None and deck.rovers.land_time == pytest.approx(r.land_time - 0.5 / 1.0)
    del d["carrier"]["deck_height"]
    assert r.accel == pytest.approx(5.0 / (5.0 / 2.5 + apm.COPTER_LEG_OVERHEAD)) and r.accel < 2.5
    d["rovers"].update(takeoff_time=1.5, land_time=2.5)  # given in the file: kept
    kept = fitted_handling(mission_from(d, tmp_path), [ArduPilot()])
    assert kept is not None and (kept.rovers.takeoff_time, kept.rovers.land_time) == (1.5, 2.5)
    assert fitted_handling(m, []) is None
    carrier = fitted_handling(m, [], ArduPilot(M.MAV_TYPE_GROUND_ROVER))
    assert carrier is not None and carrier.rovers == m.rovers and m.carrier.accel is not None
    c = m.carrier
    expected = c.max_speed / (c.max_speed / c.accel + apm.ROVER_LEG_OVERHEAD)
    assert carrier.carrier.accel == pytest.approx(expected)
    # the carrier turns at the rate its firmware's legs cost, whatever the mission said
    assert carrier.carrier.turn_rate == pytest.approx(1.0 / apm.ROVER_TURN_COST) != c.turn_rate
    copter_carrier = fitted_handling(m, [], ArduPilot())
    assert copter_carrier is not None and copter_carrier.carrier.turn_rate == c.turn_rate


def test_the_copters_touch_down_term_holds_the_auto_disarm_only_where_load_time_does_not_cover_it(
        tmp_path: Path) -> None:
    # the run loads a rover from its touch-down on while its autopilot disarms it: the plan's
    # land_time + load_time is the landing plus the longer of the two, never their sum
    d = mission_dict(carrier_connection="udpin://127.0.0.1:14599")
    d["rovers"].update(land_speed=2.0)
    lands = {}
    for load in (0.0, 1.0, 2.0, 5.0):
        d["carrier"]["load_time"] = load
        fitted = fitted_handling(mission_from(d, tmp_path), [ArduPilot()])
        assert fitted is not None
        lands[load] = fitted.rovers.land_time
    down = MEET_HEIGHT / 2.0 + apm.COPTER_TOUCHDOWN_OVERHEAD
    assert lands[0.0] == pytest.approx(down + apm.COPTER_DISARM_DELAY)
    assert lands[1.0] + 1.0 == pytest.approx(down + apm.COPTER_DISARM_DELAY)
    assert lands[5.0] == pytest.approx(down)  # the disarm is over long before the loading
    assert lands[2.0] + 2.0 == pytest.approx(down + max(2.0, apm.COPTER_DISARM_DELAY))


def test_firmware_speeds_default_to_set_on_real_links_and_keep_on_the_sim(tmp_path: Path) -> None:
    sim = mission_from(mission_dict(), tmp_path)
    assert (sim.carrier.firmware_speeds, sim.rovers.firmware_speeds) == ("keep", "keep")
    real = mission_from(mission_dict(carrier_connection="udpin://127.0.0.1:14599"), tmp_path)
    assert (real.carrier.firmware_speeds, real.rovers.firmware_speeds) == ("set", "set")
    d = mission_dict(carrier_connection="udpin://127.0.0.1:14599")
    d["rovers"]["firmware_speeds"] = "keep"
    assert mission_from(d, tmp_path).rovers.firmware_speeds == "keep"
    d["rovers"]["firmware_speeds"] = "fast"
    with pytest.raises(MissionError, match="firmware_speeds"):
        mission_from(d, tmp_path)


def documented_params(text: str) -> set[str]:
    """The parameter names in the tables of docs/autopilots.md (first column cells like `A`, `B`)."""
    cells = re.findall(r"\| ((?:`[A-Z_0-9]+`(?:, )?)+) \|", text)
    return {n for cell in cells for n in re.findall(r"`([A-Z_0-9]+)`", cell)}


def test_docs_autopilots_states_the_measured_constants_and_every_parameter() -> None:
    text = DOC.read_text()
    assert f"+ {apm.COPTER_TAKEOFF_OVERHEAD:.1f} s" in text
    assert (f"+ {apm.COPTER_TOUCHDOWN_OVERHEAD:.1f} s + max(0, {apm.COPTER_DISARM_DELAY:.1f} s − load_time)"
            in text)
    assert f"more than {RETARGET_OFFSET:g} m off the stop" in text  # the re-target the term includes
    assert f"(v/a + {apm.COPTER_LEG_OVERHEAD:.1f} s)" in text
    assert f"(v/a + {apm.ROVER_LEG_OVERHEAD:.1f} s)" in text
    assert f"{apm.ROVER_TURN_COST:.1f} s per radian" in text
    assert f"more than {HOME_ALT_TOLERANCE:g} m off" in text
    names = documented_params(text)
    for p in (*apm.COPTER_SPEEDS, *apm.ROVER_SPEEDS):
        assert p.name in names, p.name
        if p.scale == 100.0:  # cm/s rows state the range set
            assert f"{p.lo:g} – {p.hi:g}" in text, p.name


def test_docs_autopilots_states_the_deck_of_the_json_physics() -> None:
    from sitl.json_physics import Deck

    deck = Deck()
    assert f"({deck.height:g} m high, {deck.radius:g} m" in DOC.read_text()


def test_px4_handling_is_planned_and_documented(tmp_path: Path) -> None:
    from fleetctl.mavlink.autopilots import px4

    d = mission_dict(carrier_connection="udpin://127.0.0.1:14599")
    d["rovers"].update(max_speed=5.0, accel=3.0, climb_rate=1.5, land_speed=0.7)
    fitted = fitted_handling(mission_from(d, tmp_path), [px4.Px4(M.MAV_TYPE_QUADROTOR)])
    assert fitted is not None
    r = fitted.rovers
    assert r.takeoff_time == pytest.approx(TAKEOFF_HEIGHT / 1.5 + px4.MC_TAKEOFF_OVERHEAD)
    # disarmed at once when its land detector reports it landed: no auto-disarm in the term
    assert px4.Px4(M.MAV_TYPE_QUADROTOR).disarm_when_landed
    assert r.land_time == pytest.approx(MEET_HEIGHT / 0.7 + px4.MC_TOUCHDOWN_OVERHEAD)
    assert r.accel == pytest.approx(5.0 / (5.0 / 3.0 + px4.MC_LEG_OVERHEAD))
    assert px4.Px4(M.MAV_TYPE_GROUND_ROVER).handling_times(1.5, 0.7) is None  # a carrier: none
    # a deck 0.5 m up: the rover comes down 2.5 m from the approach height, not 3
    d["carrier"]["deck_height"] = 0.5
    on_deck = fitted_handling(mission_from(d, tmp_path), [px4.Px4(M.MAV_TYPE_QUADROTOR)])
    assert on_deck is not None
    assert on_deck.rovers.land_time == pytest.approx((MEET_HEIGHT - 0.5) / 0.7 + px4.MC_TOUCHDOWN_OVERHEAD)
    # an Ackermann carrier turns at what its legs cost per radian, whatever the mission said; its
    # legs keep the mission's acceleration
    carrier = fitted_handling(mission_from(d, tmp_path), [], px4.Px4(M.MAV_TYPE_GROUND_ROVER))
    c = mission_from(d, tmp_path).carrier
    assert carrier is not None and carrier.carrier.accel == c.accel
    assert carrier.carrier.turn_rate == pytest.approx(1.0 / px4.ROVER_TURN_COST) != c.turn_rate
    text = DOC.read_text()
    assert f"1 / ({px4.ROVER_TURN_COST:.1f} s per radian)" in text
    assert f"`TAKEOFF_HEIGHT / climb_rate + {px4.MC_TAKEOFF_OVERHEAD:.1f} s`" in text
    assert f"`descent / land_speed + {px4.MC_TOUCHDOWN_OVERHEAD:.1f} s`" in text
    assert f"`v / (v/a + {px4.MC_LEG_OVERHEAD:.1f} s)`" in text
    names = documented_params(text)
    for p in (*px4.MC_SPEED_PARAMS, *px4.ROVER_SPEED_PARAMS):
        assert p.name in names, p.name
    assert "| PX4 | v1.18" in text  # the tested firmware table


def test_px4_lands_at_the_mission_s_landing_speed_and_detects_it_below_that(tmp_path: Path) -> None:
    from fleetctl.mavlink.autopilots import px4

    values = px4.Px4(M.MAV_TYPE_QUADROTOR).speed_values(
        {"max_speed": 5.0, "accel": 3.0, "climb_rate": 1.5, "land_speed": 0.7})
    # the crawl below MPC_LAND_ALT3 at the speed planned, and the land detector's threshold written
    # after it (PX4 caps LNDMC_Z_VEL_MAX at min(MPC_LAND_CRWL, MPC_LAND_SPEED) / 1.2)
    assert values["MPC_LAND_CRWL"] == values["MPC_LAND_SPEED"] == 0.7
    names = list(values)
    assert names.index("LNDMC_Z_VEL_MAX") > names.index("MPC_LAND_CRWL")
    assert values["LNDMC_Z_VEL_MAX"] == pytest.approx(0.7 * px4.LAND_DETECT_RATIO)
    assert values["LNDMC_Z_VEL_MAX"] < 0.7 / 1.2


def test_px4_legs_are_not_slowed_by_the_vertical_limits() -> None:
    """A leg is the time model's straight 3D line at ``max_speed``: PX4's auto-mode vertical limits
    (and their caps, written first) follow ``max_speed``; the take-off and the landing keep
    ``climb_rate`` and ``land_speed`` (measured on SITL 1.18: with MPC_Z_V_AUTO_DN at the landing
    speed, a rover collected from 9.7 m up took 10 s to come down 6.7 m, +37 % on the collection)."""
    from fleetctl.mavlink.autopilots import px4

    values = px4.Px4(M.MAV_TYPE_QUADROTOR).speed_values(
        {"max_speed": 5.0, "accel": 3.0, "climb_rate": 1.5, "land_speed": 0.7})
    for up_or_down in ("UP", "DN"):
        assert values[f"MPC_Z_VEL_MAX_{up_or_down}"] == values[f"MPC_Z_V_AUTO_{up_or_down}"] == 5.0
        names = list(values)
        assert names.index(f"MPC_Z_VEL_MAX_{up_or_down}") < names.index(f"MPC_Z_V_AUTO_{up_or_down}")
    assert values["MPC_TKO_SPEED"] == 1.5 and values["MPC_LAND_SPEED"] == 0.7
    fast = px4.Px4(M.MAV_TYPE_QUADROTOR).speed_values({"land_speed": 2.0})
    assert fast["LNDMC_Z_VEL_MAX"] == px4.LAND_DETECT_MAX  # no looser, whatever the landing speed
    text = DOC.read_text()
    assert "`LNDMC_Z_VEL_MAX`" in text and "`MPC_LAND_CRWL`" in text
    assert f"{px4.LAND_DETECT_RATIO:g} × `rovers.land_speed`, at most {px4.LAND_DETECT_MAX:g} m/s" in text


def test_docs_state_how_long_a_landed_rover_is_given_to_disarm() -> None:
    from fleetctl.run.collect import DISARM_WAIT

    text = (DOC.parent / "mavlink.md").read_text()
    assert f"after {DISARM_WAIT:g} s it is\ntold to" in text


def test_docs_state_when_a_rover_is_landed_over_the_carrier_instead_of_the_stop() -> None:
    from fleetctl.run.collect import RETARGET_DONE, RETARGET_NEAR, RETARGET_OFFSET, RETARGET_SPEED

    text = (DOC.parent / "mavlink.md").read_text()
    assert f"more than {RETARGET_OFFSET:g} m off the carrier" in text
    from pymavlink.dialects.v20 import ardupilotmega as M

    from fleetctl.mavlink.autopilots import Px4
    assert f"travels on {Px4(M.MAV_TYPE_QUADROTOR).land_travel:g} s of the rover's horizontal speed" in text
    assert (f"once within {RETARGET_DONE:g} m of it at {RETARGET_SPEED:g} m/s at most, or at rest within "
            f"{RETARGET_NEAR:g} m") in text
