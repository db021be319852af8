"""sitl.json_physics: the models alone, the JSON wire format and lockstep server, and real ArduPilot
firmware (ArduCopter, ArduRover) flying on them, a copter riding a carrier's deck."""

from __future__ import annotations

import argparse
import math
import socket
from collections.abc import Iterator
from contextlib import contextmanager

import pytest
from firmware_gcs import ACCEPTED, SyncGcs

from sitl.firmware import ArduPilotBuild, FirmwareFleet, find_ardupilot
from sitl.json_physics import Deck, JsonServer, JsonWorld, QuadParams, World
from sitl.json_physics.protocol import encode_servo, encode_state, parse_servo
from sitl.json_physics.rigid import GRAVITY, euler, yaw_of

DT = 1.0 / 400
QUAD = QuadParams()
HOVER = round(QUAD.pwm_for(QUAD.hover_thrust))
IDLE = [1000] * 4 + [0] * 12


def quad(*pwm: float) -> list[int]:
    return [round(p) for p in pwm] + [0] * (16 - len(pwm))


def drive(throttle: int, steering: int = 1500) -> list[int]:
    return [steering, 0, throttle] + [0] * 13


def airborne(world: World, name: str, down: float) -> None:
    v = world.vehicles[name]
    v.support = None
    n, e, _ = v.body.position
    v.body.position = (n, e, down)
    v.body.velocity = (0.0, 0.0, 0.0)
    v.model.thrusts[:] = [QUAD.max_thrust * QUAD.hover_thrust] * 4  # type: ignore[union-attr]


def carrier_world() -> World:
    w = World()
    w.add_ground_vehicle("carrier", 20, deck=Deck(height=0.5, radius=1.5))
    w.add_copter("r1", 21, north=0.5, east=-0.3, on_deck_of="carrier")
    return w


# -- models -------------------------------------------------------------------------------------
def test_hover_thrust_holds_the_weight() -> None:
    w = World()
    w.add_copter("q", 20)
    airborne(w, "q", -10.0)
    for _ in range(800):
        b = w.step("q", quad(HOVER, HOVER, HOVER, HOVER), DT)
    assert abs(b.velocity[2]) < 0.1 and abs(b.position[2] + 10.0) < 0.1  # pwm in whole microseconds
    assert max(abs(a) for a in euler(b.attitude)) < 1e-9
    # the accelerometer reads the rotors' specific force: -g in hover
    assert b.accel_body[2] == pytest.approx(-GRAVITY, abs=0.05)


@pytest.mark.parametrize(("motor", "axis", "sign"), [(0, 0, -1), (1, 0, 1), (2, 1, 1), (3, 1, -1)])
def test_plus_frame_motor_positions(motor: int, axis: int, sign: int) -> None:
    """ch1 right, ch2 left, ch3 front, ch4 back: more thrust on one side rolls/pitches away from it."""
    w = World()
    w.add_copter("q", 20)
    airborne(w, "q", -10.0)
    pwm = [HOVER] * 4
    pwm[motor] += 50
    for _ in range(40):
        b = w.step("q", quad(*pwm), DT)
    assert sign * b.gyro[axis] > 0.2
    assert abs(b.gyro[1 - axis]) < 0.01 * abs(b.gyro[axis])  # gyroscopic coupling only


def test_plus_frame_yaw_sign() -> None:
    """ch1 and ch2 spin counter-clockwise: more of them yaws the nose right (positive)."""
    w = World()
    w.add_copter("q", 20)
    airborne(w, "q", -10.0)
    for _ in range(100):
        b = w.step("q", quad(HOVER + 40, HOVER + 40, HOVER - 40, HOVER - 40), DT)
    assert b.gyro[2] > 0.2 and abs(b.gyro[0]) < 1e-9 and abs(b.gyro[1]) < 1e-9


def test_ground_contact_stops_a_fall_and_holds() -> None:
    w = World()
    w.add_copter("q", 20)
    airborne(w, "q", -5.0)
    v = w.vehicles["q"]
    v.body.velocity = (3.0, 1.0, 0.0)
    for _ in range(2000):
        b = w.step("q", IDLE, DT)
        assert b.position[2] <= 0.0
    assert b.position[2] == 0.0 and b.velocity == (0.0, 0.0, 0.0)
    assert v.support is not None and v.support.carrier is None
    assert b.accel_body == pytest.approx((0.0, 0.0, -GRAVITY))
    # friction: it stays where it touched down, below hover thrust it does not lift
    where = b.position
    for _ in range(400):
        b = w.step("q", quad(HOVER - 20, HOVER - 20, HOVER - 20, HOVER - 20), DT)
    assert b.position == where


def test_accelerometer_reports_the_whole_touch_down() -> None:
    """What the accelerometer reports adds up to the velocity the copter gained and lost: a
    touch-down that stops it in one step is reported over the following steps (a firmware
    estimator that missed part of it would believe the copter still sinks, through the ground)."""
    w = World()
    w.add_copter("q", 20)
    airborne(w, "q", -3.0)
    v = w.vehicles["q"]
    v.body.velocity = (2.0, 1.0, 0.0)
    felt = [0.0, 0.0, 0.0]
    fastest = 0.0
    for _ in range(1600):
        b = w.step("q", IDLE, DT)
        fastest = max(fastest, b.velocity[2])
        a = euler(b.attitude)  # level: body and earth axes agree (checked below)
        assert abs(a[0]) < 1e-6 and abs(a[1]) < 1e-6
        fx, fy, fz = b.accel_body
        felt = [felt[0] + fx * DT, felt[1] + fy * DT, felt[2] + (fz + GRAVITY) * DT]
    assert v.support is not None and fastest > 3.0  # it fell fast and landed
    assert b.velocity == (0.0, 0.0, 0.0)
    assert felt == pytest.approx([-2.0, -1.0, 0.0], abs=0.05)


def test_ground_vehicle_drives_and_turns() -> None:
    w = World()
    w.add_ground_vehicle("c", 20)
    for _ in range(8000):
        b = w.step("c", drive(1650), DT)
    assert b.velocity[0] == pytest.approx(0.3 * 20.0, rel=0.01)  # 30 % of SIM_Rover's 20 m/s
    for _ in range(200):
        b = w.step("c", drive(1650, 1800), DT)
    assert b.gyro[2] > 0.5 and yaw_of(b.attitude) > 0.3            # steering right turns right
    for _ in range(4000):
        b = w.step("c", drive(1500, 1500), DT)
    assert b.velocity == (0.0, 0.0, 0.0)


def test_ground_vehicle_moves_from_rest_on_any_throttle() -> None:
    """As ArduPilot's SIM_Rover: no static friction holds it, forwards or back -- a speed
    controller whose demand starts near zero still moves it -- and unpowered it comes to rest."""
    for pwm, sign in ((1510, 1.0), (1490, -1.0)):  # 2 % of throttle either way
        w = World()
        w.add_ground_vehicle("c", 20)
        for _ in range(400):
            b = w.step("c", drive(pwm), DT)
        assert sign * b.velocity[0] > 0.1  # 0.16 m/s after 1 s, on its way to 0.4
        for _ in range(2000):
            b = w.step("c", drive(1500), DT)
        assert b.velocity == (0.0, 0.0, 0.0)


def test_copter_on_deck_follows_a_driving_carrier() -> None:
    w = carrier_world()
    c, r = w.vehicles["carrier"], w.vehicles["r1"]
    assert r.body.position == pytest.approx((0.5, -0.3, -0.5))
    for k in range(2800):
        w.step("carrier", drive(1650, 1500 if k < 2400 else 1550), DT)
        b = w.step("r1", IDLE, DT)
        cyaw = yaw_of(c.body.attitude)
        cn, ce, _ = c.body.position
        want = (cn + 0.5 * math.cos(cyaw) + 0.3 * math.sin(cyaw),
                ce + 0.5 * math.sin(cyaw) - 0.3 * math.cos(cyaw))
        assert b.position[:2] == pytest.approx(want, abs=1e-9)
        assert b.position[2] == -0.5
    assert c.body.position[0] > 20.0 and yaw_of(c.body.attitude) > 0.5
    assert w.on_deck("r1") == "carrier"
    assert yaw_of(b.attitude) == pytest.approx(yaw_of(c.body.attitude))
    assert b.gyro[2] == c.body.gyro[2] > 0
    assert math.hypot(*b.velocity[:2]) == pytest.approx(math.hypot(*c.body.velocity[:2]), rel=0.05)


def test_lift_off_leaves_the_deck_and_landing_on_the_stopped_carrier_boards_it() -> None:
    w = carrier_world()
    for k in range(4400):                                # drive 1 s, stop, ride along
        w.step("carrier", drive(1700 if k < 400 else 1500), DT)
        w.step("r1", IDLE, DT)
    c = w.vehicles["carrier"].body
    assert c.position[0] > 1.0 and c.velocity == (0.0, 0.0, 0.0) and w.on_deck("r1") == "carrier"
    climb = round(QUAD.pwm_for(0.5))
    for _ in range(200):
        b = w.step("r1", quad(climb, climb, climb, climb), DT)
    assert w.on_deck("r1") is None and b.position[2] < -0.6
    for _ in range(4000):                                 # it sinks back
        b = w.step("r1", quad(HOVER - 30, HOVER - 30, HOVER - 30, HOVER - 30), DT)
    assert w.on_deck("r1") == "carrier" and b.position[2] == -0.5


def test_landing_beside_the_deck_is_on_the_ground() -> None:
    w = carrier_world()
    airborne(w, "r1", -3.0)
    r = w.vehicles["r1"]
    r.body.position = (3.0, 0.0, -3.0)
    for _ in range(2000):
        b = w.step("r1", IDLE, DT)
    assert w.on_deck("r1") is None and b.position[2] == 0.0


# -- wire format and server ---------------------------------------------------------------------
def test_state_line_is_compact_and_framed() -> None:
    w = carrier_world()
    line = encode_state(1.5, w.vehicles["r1"].body, (0.0, 0.0, -0.5)).decode()
    assert line.startswith("\n{") and line.endswith("}\n") and " " not in line
    assert '"position":[0.5,-0.3,0.0]' in line and '"quaternion":[1.0,0.0,0.0,0.0]' in line
    assert '"gyro":[' in line and '"accel_body":[' in line and '"timestamp":1.5' in line


def test_servo_packets_round_trip() -> None:
    pkt = parse_servo(encode_servo(1200, 7, (1100, 1200)))
    assert pkt is not None and pkt.frame_rate == 1200 and pkt.frame_count == 7
    assert pkt.pwm[:3] == (1100, 1200, 0) and len(pkt.pwm) == 16
    assert len(parse_servo(encode_servo(400, 1, tuple(range(1000, 1032)))).pwm) == 32  # type: ignore[union-attr]
    assert parse_servo(b"\x00" * 40) is None


def test_server_answers_each_packet_in_lockstep() -> None:
    w = World()
    w.add_copter("q", 20)
    server = JsonServer(w, ports={"q": 0}).start()
    try:
        port = server._links[0].sock.getsockname()[1]
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.settimeout(2.0)
            replies = []
            for n in (0, 1, 2, 2):
                s.sendto(encode_servo(400, n, tuple(IDLE)), ("127.0.0.1", port))
                replies.append(s.recv(4096))
        assert [r.split(b",")[0] for r in replies] == [b'\n{"timestamp":0.0025', b'\n{"timestamp":0.005',
                                                       b'\n{"timestamp":0.0075', b'\n{"timestamp":0.0075']
        assert server.stats["q"].packets == 3 and server.stats["q"].repeats == 1
    finally:
        server.stop()


def test_a_port_already_held_is_named_and_the_others_are_released() -> None:
    w = World()
    w.add_copter("a", 20)
    w.add_copter("b", 21)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as held, \
            socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        held.bind(("127.0.0.1", 0))
        probe.bind(("127.0.0.1", 0))
        free = probe.getsockname()[1]
        probe.close()
        busy = held.getsockname()[1]
        with pytest.raises(OSError, match=f"b: cannot listen on UDP 127.0.0.1:{busy}"):
            JsonServer(w, ports={"a": free, "b": busy}).start()
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as again:
            again.bind(("127.0.0.1", free))  # a's port was closed when b's failed


def test_server_keeps_the_vehicles_on_one_clock() -> None:
    """A vehicle ahead of the slowest active one by more than max_skew waits for it; a vehicle
    silent for active_timeout no longer holds the others."""
    w = World()
    w.add_copter("a", 20)
    w.add_copter("b", 21)
    server = JsonServer(w, ports={"a": 0, "b": 0}, max_skew=0.01, active_timeout=0.6).start()
    try:
        port = {link.name: link.sock.getsockname()[1] for link in server._links}
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as a, \
                socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as b:
            a.settimeout(0.3)
            b.settimeout(1.0)
            b.sendto(encode_servo(400, 0, tuple(IDLE)), ("127.0.0.1", port["b"]))
            assert b.recv(4096).startswith(b'\n{"timestamp":0.0025,')
            answered = 0
            for n in range(10):       # a joins at b's 2.5 ms, may run 10 ms ahead of it (5 steps)
                a.sendto(encode_servo(400, n, tuple(IDLE)), ("127.0.0.1", port["a"]))
                try:
                    a.recv(4096)
                except TimeoutError:
                    break
                answered += 1
            assert answered == 5 and server.stats["a"].held > 0
            b.sendto(encode_servo(400, 1, tuple(IDLE)), ("127.0.0.1", port["b"]))
            b.recv(4096)
            assert a.recv(4096).startswith(b'\n{"timestamp":0.015')   # b moved on: a's held answer
            a.settimeout(2.0)          # b falls silent: after active_timeout a runs alone
            for n in range(6, 40):
                a.sendto(encode_servo(400, n, tuple(IDLE)), ("127.0.0.1", port["a"]))
                a.recv(4096)
        assert w.vehicles["a"].time == pytest.approx(40 / 400)
    finally:
        server.stop()


def test_command_line_vehicles() -> None:
    from sitl.json_physics.__main__ import _vehicle

    assert _vehicle("r1=21@carrier") == ("r1", 21, 0.0, 0.0, 0.0, "carrier")
    assert _vehicle("c=20,10,-5,90") == ("c", 20, 10.0, -5.0, 90.0, None)
    with pytest.raises(argparse.ArgumentTypeError):
        _vehicle("r1=21,3")


# -- real firmware on this physics ---------------------------------------------------------------
HOME = (47.397742, 8.545594, 488.0)
SPEEDUP = 4
FIRMWARE = {"SIM_RATE_HZ": 400}   # physics steps at the copter's loop rate: a third of the default
COPTER_GUIDED, COPTER_LAND, ROVER_GUIDED = 4, 9, 15
TAKEOFF = 22  # MAV_CMD_NAV_TAKEOFF


@pytest.fixture
def ardupilot() -> ArduPilotBuild:
    build = find_ardupilot()
    if build is None:
        pytest.skip("ArduPilot SITL not found: set FLEETCTL_ARDUPILOT_DIR")
    return build


@contextmanager
def flying(world: JsonWorld, build: ArduPilotBuild, port: int) -> Iterator[SyncGcs]:
    """The world's physics, its firmware vehicles at ``speedup`` 4, and a GCS on ``port`` that has
    heard every vehicle and asked for its telemetry."""
    gcs = SyncGcs(port)
    fleet = FirmwareFleet(build, world.firmware_vehicles(), gcs_port=port, speedup=SPEEDUP,
                          instance_base=world.instance_base)
    try:
        with world, fleet:
            sysids = [v.sysid for v in fleet.vehicles]
            gcs.wait(lambda: all(s in gcs.addr for s in sysids), 60, "heartbeats")
            for s in sysids:
                gcs.request_streams(s)
            yield gcs
    finally:
        fleet.cleanup()
        gcs.close()


def north_east(pos: tuple[float, float, float] | None) -> tuple[float, float]:
    """A GLOBAL_POSITION_INT's (lat, lon, rel alt) as metres north/east of HOME."""
    assert pos is not None
    r = 6378137.0
    return (math.radians(pos[0] - HOME[0]) * r,
            math.radians(pos[1] - HOME[1]) * r * math.cos(math.radians(HOME[0])))


def offset(north: float, east: float = 0.0) -> tuple[float, float]:
    r = 6378137.0
    return (HOME[0] + math.degrees(north / r),
            HOME[1] + math.degrees(east / (r * math.cos(math.radians(HOME[0])))))


def sim_time(world: JsonWorld, name: str) -> float:
    return world.world.vehicles[name].time


def hold_for(gcs: SyncGcs, world: JsonWorld, name: str, seconds: float) -> list[tuple[float, float, float]]:
    """Simulated ``seconds`` of telemetry: the physics positions (NED) seen meanwhile."""
    end = sim_time(world, name) + seconds
    seen = []

    def done() -> bool:
        seen.append(world.state(name).position)
        return sim_time(world, name) >= end
    gcs.wait(done, 10 + 2 * seconds, f"{seconds} simulated seconds")
    return seen


def disarmed(gcs: SyncGcs, sysid: int) -> bool:
    hb = gcs.msg(sysid, "HEARTBEAT")
    return hb is not None and not hb.base_mode & 128


def test_arducopter_flies_on_json_physics(ardupilot: ArduPilotBuild) -> None:
    world = JsonWorld(HOME, instance_base=20)
    world.add_copter("r1", 11, firmware_params=FIRMWARE)
    with flying(world, ardupilot, 14620) as gcs:
        gcs.arm(11, COPTER_GUIDED, 150)
        armable = sim_time(world, "r1")
        assert gcs.command(11, TAKEOFF, 0, 0, 0, 0, 0, 0, 5) == ACCEPTED
        gcs.wait(lambda: (gcs.position(11) or (0, 0, 0))[2] > 4.7, 60, "5 m")
        hold_for(gcs, world, "r1", 3.0)   # settle
        hold = hold_for(gcs, world, "r1", 8.0)
        alts = [-p[2] for p in hold]
        drift = max(math.hypot(p[0], p[1]) for p in hold)
        assert 4.5 < min(alts) and max(alts) < 5.5 and drift < 0.5
        lat, lon = offset(20.0)
        gcs.goto(11, lat, lon, 5.0)
        start = sim_time(world, "r1")
        gcs.wait(lambda: math.dist(north_east(gcs.position(11)), (20.0, 0.0)) < 0.5
                 and math.dist(world.state("r1").position[:2], (20.0, 0.0)) < 0.5, 60, "20 m north")
        leg = sim_time(world, "r1") - start
        gcs.set_mode(11, COPTER_LAND)
        gcs.wait(lambda: world.state("r1").position[2] == 0.0 and disarmed(gcs, 11), 120, "land, disarm")
        landed = world.state("r1").position
        assert math.dist(landed[:2], (20.0, 0.0)) < 1.0
        print(f"\narmable at {armable:.1f} s sim; hover {min(alts):.2f}..{max(alts):.2f} m, drift "
              f"{drift:.2f} m; 20 m leg {leg:.1f} s; landed at {landed[0]:.2f}, {landed[1]:.2f}")


def test_carrier_on_json_physics_carries_a_copter_that_flies_off_and_back(ardupilot: ArduPilotBuild) -> None:
    world = JsonWorld(HOME, instance_base=22)
    world.add_carrier("carrier", 1, firmware_params=FIRMWARE)
    world.add_copter("r1", 11, on_deck_of="carrier", firmware_params=FIRMWARE)
    assert world.home("r1")[2] == pytest.approx(HOME[2] + 0.5)   # its home is on the deck
    with flying(world, ardupilot, 14621) as gcs:
        gcs.arm(1, ROVER_GUIDED, 240)
        carrier_armed = sim_time(world, "carrier")
        gcs.wait(lambda: gcs.position(11) is not None, 30, "copter position")
        lat, lon = offset(25.0)
        gcs.goto(1, lat, lon, 0.0)
        lag = 0.0

        def arrived() -> bool:
            nonlocal lag
            assert world.on_deck("r1") == "carrier"
            lag = max(lag, math.dist(north_east(gcs.position(11)), north_east(gcs.position(1))))
            c = world.state("carrier")
            return math.dist(c.position[:2], (25.0, 0.0)) < 3.0 and math.hypot(*c.velocity[:2]) < 0.05
        gcs.wait(arrived, 90, "the carrier 25 m north")
        hold_for(gcs, world, "r1", 5.0)
        carrier, copter = north_east(gcs.position(1)), north_east(gcs.position(11))
        assert copter[0] > 20.0 and math.dist(copter, carrier) < 1.5   # two EKFs' estimates
        assert lag < 5.0   # the copter's GPS and EKF follow the carrier's motion with some delay
        assert abs(gcs.position(11)[2]) < 0.5   # type: ignore[index]  # still on its home height
        gcs.arm(11, COPTER_GUIDED, 60)
        assert gcs.command(11, TAKEOFF, 0, 0, 0, 0, 0, 0, 5) == ACCEPTED
        gcs.wait(lambda: (gcs.position(11) or (0, 0, 0))[2] > 4.5, 60, "5 m above the deck")
        assert world.on_deck("r1") is None
        r1 = world.state("r1").position
        c = world.state("carrier").position
        assert math.dist(r1[:2], c[:2]) < 1.5 and r1[2] < -4.5
        gcs.set_mode(11, COPTER_LAND)     # back onto the stopped carrier's deck
        landing = sim_time(world, "r1")
        gcs.wait(lambda: world.on_deck("r1") == "carrier" and disarmed(gcs, 11), 120, "land on the deck")
        back = world.state("r1").position
        landing = sim_time(world, "r1") - landing
        print(f"\ncarrier armable at {carrier_armed:.1f} s sim; copter GPS lag behind carrier <= {lag:.2f} m;"
              f" after 25 m: carrier {carrier[0]:.2f},{carrier[1]:.2f}"
              f" copter {copter[0]:.2f},{copter[1]:.2f};"
              f" took off to {-r1[2]:.2f} m (world); landed back on the deck at {back[0] - c[0]:.2f},"
              f"{back[1] - c[1]:.2f} from the carrier, {landing:.1f} s to land and disarm")
