"""PX4's simulator interface of ``sitl.json_physics`` against a scripted PX4 end: a TCP client that
speaks MAVLink 2 as ``simulator_mavlink`` does (connects, reads HIL_SENSOR and HIL_STATE_QUATERNION,
answers with HIL_ACTUATOR_CONTROLS stamped with the time it was sent)."""

from __future__ import annotations

import math
import socket
import time
from collections.abc import Iterator
from contextlib import contextmanager

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from sitl.geo import LocalFrame
from sitl.json_physics import Deck, px4_hil
from sitl.json_physics.api import PX4_QUAD, PX4_ROVER
from sitl.json_physics.multicopter import X_MOTORS_PX4, Multicopter
from sitl.json_physics.px4_hil import Px4HilServer
from sitl.json_physics.rigid import GRAVITY, euler
from sitl.json_physics.world import World

ORIGIN = (47.397742, 8.545594, 488.0)
ARMED = mavlink2.MAV_MODE_FLAG_SAFETY_ARMED


class FakePx4:
    """One firmware's end of the link."""

    def __init__(self, port: int) -> None:
        deadline = time.monotonic() + 5.0
        while True:
            try:
                self.sock = socket.create_connection(("127.0.0.1", port), timeout=2.0)
                break
            except ConnectionRefusedError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.05)
        self.mav = mavlink2.MAVLink(None, 1, 1)
        self.mav.robust_parsing = True
        self.pending: list[object] = []

    def recv(self, kind: str, timeout: float = 5.0) -> mavlink2.MAVLink_message:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            while self.pending:
                m = self.pending.pop(0)
                assert isinstance(m, mavlink2.MAVLink_message)
                if m.get_type() == kind:
                    return m
            data = self.sock.recv(65536)
            assert data, "the world closed the link"
            self.pending += self.mav.parse_buffer(data) or []
        raise AssertionError(f"no {kind} within {timeout} s")

    def answer(self, controls: list[float], armed: bool = True) -> None:
        """Controls for the latest sensor step (stamped with its time)."""
        t = self.recv("HIL_SENSOR").time_usec
        msg = self.mav.hil_actuator_controls_encode(t, controls + [0.0] * (16 - len(controls)),
                                                    ARMED if armed else 0, 1)
        self.sock.sendall(msg.pack(self.mav))

    def close(self) -> None:
        self.sock.close()


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@contextmanager
def served(world: World, speed: float = 20.0) -> Iterator[Px4HilServer]:
    ports = {name: _free_port() for name in world.vehicles}
    server = Px4HilServer(world, ORIGIN, ports=ports, speed=speed).start()
    try:
        yield server
    finally:
        server.stop()


def test_a_quad_is_sent_its_imu_and_ground_truth_on_one_clock() -> None:
    world = World()
    world.add_copter("r1", 0, north=10.0, east=5.0, params=PX4_QUAD)
    with served(world) as server:
        px4 = FakePx4(server.ports["r1"])
        try:
            first = px4.recv("HIL_SENSOR")
            state = px4.recv("HIL_STATE_QUATERNION")
            later = px4.recv("HIL_SENSOR")
        finally:
            px4.close()
    assert later.time_usec > first.time_usec > 0
    assert first.fields_updated == 0b111111  # accelerometer and gyroscope: PX4 simulates the rest
    assert first.zacc == pytest.approx(-GRAVITY, abs=0.1) and abs(first.xacc) < 0.1  # standing, level
    lat, lon, alt = LocalFrame(*ORIGIN).to_geodetic(5.0, 10.0, 0.0)  # east, north, up (pymap3d)
    assert abs(state.lat - lat * 1e7) <= 1 and abs(state.lon - lon * 1e7) <= 1  # within 1e-7 degree
    assert abs(state.alt - alt * 1000) <= 1
    assert list(state.attitude_quaternion) == pytest.approx([1.0, 0.0, 0.0, 0.0])


def _fly(world: World, controls: list[float], armed: bool, steps: int) -> None:
    with served(world) as server:
        px4 = FakePx4(server.ports["r1"])
        try:
            for _ in range(steps):
                px4.answer(controls, armed)
        finally:
            px4.close()


def test_armed_controls_above_hover_lift_the_quad_and_disarmed_ones_do_not() -> None:
    lift = [0.6] * 4  # PX4's quad hovers at 0.49
    world = World()
    world.add_copter("r1", 0, params=PX4_QUAD)
    _fly(world, lift, armed=True, steps=300)
    assert world.vehicles["r1"].body.position[2] < -0.3 and world.on_deck("r1") is None

    world = World()
    world.add_copter("r1", 0, params=PX4_QUAD)
    _fly(world, lift, armed=False, steps=300)
    assert world.vehicles["r1"].body.position[2] == 0.0


def test_the_px4_quad_x_rolls_and_turns_as_its_outputs_say() -> None:
    """PX4's rotor order (CA_ROTOR0..3: front right, back left, front left, back right; the first
    two spin CCW): more thrust on the left rotors rolls it right, on the CCW rotors turns it right."""
    assert X_MOTORS_PX4 == PX4_QUAD.motors
    for outputs, axis in (([0.5, 0.6, 0.6, 0.5], 0), ([0.6, 0.6, 0.5, 0.5], 2)):
        quad = Multicopter(PX4_QUAD)
        for _ in range(100):
            quad.drive(outputs, 0.004)
            quad.fly(0.004)
        angles = euler(quad.body.attitude)
        assert angles[axis] > 0.01, (outputs, angles)


def test_the_px4_rover_drives_on_its_throttle_output_and_carries_its_deck() -> None:
    world = World()
    world.add_ground_vehicle("carrier", 0, deck=Deck(0.5, 1.5), params=PX4_ROVER)
    world.add_copter("r1", 1, north=0.5, on_deck_of="carrier", params=PX4_QUAD)
    for _ in range(1000):  # 4 s at half throttle, straight (steering output 1, throttle output 2)
        world.step_controls("carrier", [0.0, 0.5], 0.004)
        world.step_controls("r1", [0.0] * 4, 0.004)
    carrier = world.vehicles["carrier"].body.position
    assert carrier[0] > 3.0 and abs(carrier[1]) < 1e-6
    assert world.on_deck("r1") == "carrier"
    assert world.vehicles["r1"].body.position == pytest.approx((carrier[0] + 0.5, 0.0, -0.5))


def test_a_firmware_whose_link_closes_has_its_motors_stopped() -> None:
    world = World()
    world.add_copter("r1", 0, params=PX4_QUAD)
    with served(world) as server:
        px4 = FakePx4(server.ports["r1"])
        for _ in range(300):
            px4.answer([0.6] * 4)
        px4.close()
        deadline = time.monotonic() + 10.0
        while server.stats["r1"].connects and time.monotonic() < deadline:
            with server.lock:
                if world.vehicles["r1"].support is not None:  # it fell back to the ground
                    break
            time.sleep(0.05)
        with server.lock:
            assert world.vehicles["r1"].support is not None
            assert world.vehicles["r1"].model.thrusts == pytest.approx([0.0] * 4, abs=0.01)


def test_the_docs_state_the_interface_as_built() -> None:
    from pathlib import Path

    from sitl.json_physics import px4_hil
    from sitl.json_physics.api import PX4_SIMULATOR

    text = (Path(__file__).resolve().parents[2] / "docs" / "autopilots.md").read_text()
    assert f"TCP port `{px4_hil.BASE_PORT} + instance`" in text
    assert f"`PX4_SIMULATOR={PX4_SIMULATOR}`" in text
    assert f"lag the world by more than {px4_hil.MAX_LAG * 1000:.0f} ms" in text
    assert f"four vehicles at {px4_hil.RATE} Hz" in text
    assert px4_hil.hil_port(3) == px4_hil.BASE_PORT + 3
    import importlib.util

    path = Path(__file__).parents[1] / "firmware" / "px4_fleet.py"
    spec = importlib.util.spec_from_file_location("px4_fleet", path)
    assert spec is not None and spec.loader is not None
    fleet = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(fleet)
    assert f"time, {fleet.DECK_SPEEDUP:g} in the tests" in text


def test_a_copter_riding_a_driving_carrier_feels_it_shake() -> None:
    """PX4 takes a landed vehicle with a quiet IMU to be at rest (it then holds its estimate still
    and fails its GPS drift check as the deck moves): the carrier's vibration reaches the copters
    on its deck while it drives, and stops with it."""
    world = World()
    world.add_ground_vehicle("carrier", 0, deck=Deck(0.5, 1.5), params=PX4_ROVER)
    world.add_copter("r1", 1, on_deck_of="carrier", params=PX4_QUAD)
    world.add_copter("r2", 2, north=20.0, params=PX4_QUAD)
    assert world.ground_speed("r1") == world.ground_speed("r2") == 0.0

    server = Px4HilServer(world, ORIGIN, ports={n: _free_port() for n in world.vehicles})
    mav = mavlink2.MAVLink(None, 1, 1)

    def xacc(payload: bytes) -> float:
        return next(m.xacc for m in mav.parse_buffer(payload) or [] if m.get_type() == "HIL_SENSOR")

    def spread(name: str) -> float:
        xs = [xacc(server._sensors(name)) for _ in range(200)]
        mean = sum(xs) / len(xs)
        return math.sqrt(sum((x - mean) ** 2 for x in xs) / len(xs))

    server.start()
    try:
        with server.lock:
            quiet = spread("r1")
            world.vehicles["carrier"].model.speed = 1.5  # type: ignore[union-attr]
            assert world.ground_speed("r1") == 1.5 and world.ground_speed("r2") == 0.0
            assert spread("r1") > 10 * quiet and spread("carrier") > 10 * quiet
            assert spread("r2") < 2 * quiet
    finally:
        server.stop()



def test_a_taken_port_is_named_with_its_vehicle() -> None:
    world = World()
    world.add_copter("r1", 0, params=PX4_QUAD)
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen(1)
        port = busy.getsockname()[1]
        with pytest.raises(OSError, match=f"r1: cannot listen on TCP 127.0.0.1:{port} for its PX4 firmware"):
            Px4HilServer(world, ORIGIN, ports={"r1": port}).start()


def test_the_px4_quad_is_sihs() -> None:
    """PX4's handling terms were measured on its SIH quadcopter: the deck's quad has its constants
    (SIH_MASS 1 kg, SIH_T_MAX 5 N, SIH_KDV 1 N per m/s), as docs/autopilots.md says."""
    from pathlib import Path

    assert PX4_QUAD.mass == 1.0 and PX4_QUAD.linear_drag == 1.0 and PX4_QUAD.drag == 0.0
    assert PX4_QUAD.max_thrust == pytest.approx(5.0)
    text = (Path(__file__).resolve().parents[2] / "docs" / "autopilots.md").read_text()
    assert "(1 kg, 5 N per rotor, first-order drag 1 N per m/s" in text
    assert f"({px4_hil.VIBRATION_ACCEL:g} m/s² more noise at\n{px4_hil.VIBRATION_SPEED:g} m/s)" in text


def test_the_first_order_frame_stays_within_a_millimetre_at_100_m() -> None:
    frame = LocalFrame(*ORIGIN)
    dlat, dlon = frame.degrees_per_metre()
    for east, north in ((100.0, 0.0), (0.0, -100.0), (70.0, 70.0)):
        lat, lon, _ = frame.to_geodetic(east, north, 0.0)
        assert abs(ORIGIN[0] + north * dlat - lat) * 111_000 < 1e-3
        assert abs(ORIGIN[1] + east * dlon - lon) * 111_000 * math.cos(math.radians(ORIGIN[0])) < 1e-3
