"""JsonWorld: a world of vehicles, its server, and the firmware vehicles that fly on it --
ArduPilot through its JSON interface (:mod:`.server`) or PX4 through ``simulator_mavlink``
(:mod:`.px4_hil`)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from contextlib import AbstractContextManager, nullcontext
from typing import Literal

from ..firmware import FirmwareVehicle, Frame
from .body import Body
from .ground_vehicle import GroundParams, GroundVehicle
from .location import offset
from .multicopter import X_MOTORS_PX4, QuadParams
from .px4_hil import HilStats, Px4HilServer
from .rigid import GRAVITY
from .server import JsonServer, LinkStats
from .world import Deck, World

Firmware = Literal["ardupilot", "px4"]
# PX4's SITL quad (airframe 10040) as PX4's own SIH simulates it by default: 1 kg (SIH_MASS),
# 5 N full thrust per rotor (SIH_T_MAX: hovering at 0.49, linear in the output), 0.1 N m of rotor
# torque (SIH_Q_MAX), arms 0.2 m from the roll and pitch axes (SIH_L_ROLL, SIH_L_PITCH), inertia
# SIH_IXX/IYY/IZZ, first-order drag 1 N per m/s (SIH_KDV) and angular damping 0.025 N m per rad/s
# (SIH_KDW), motor time constant 0.05 s (SIH_T_TAU); the X frame of its CA_ROTOR geometry
PX4_QUAD = QuadParams(mass=1.0, arm=0.2 * math.sqrt(2.0), inertia=(0.025, 0.025, 0.03),
                      hover_thrust=1.0 * GRAVITY / (4 * 5.0), yaw_moment=0.1 / 5.0, motor_tau=0.05,
                      drag=0.0, linear_drag=1.0, rot_damping=(0.025, 0.025, 0.025), motors=X_MOTORS_PX4)
# PX4's Ackermann rover (airframe 10045): steering on output 1, throttle on output 2; full
# throttle is RO_MAX_THR_SPEED (3.2 m/s), the speed its throttle feed-forward assumes (its speed
# loop's gains, RO_SPEED_P/I 0.001, barely correct a shortfall), with little rolling resistance
# unpowered;
# wheel base 0.321 m at RA_MAX_STR_ANG 30 degrees
PX4_ROVER = GroundParams(max_speed=3.2, max_accel=6.0, rolling=0.05,
                         turning_circle=2 * 0.321 / math.tan(math.radians(30)),
                         max_wheel_turn=30.0, steering_channel=1, throttle_channel=2)
PX4_SIMULATOR = "rotorpy"  # PX4's name for an external simulator with GPS, baro and mag simulated inside


class JsonWorld:
    """Vehicles added in order get instance numbers ``instance_base``, ``instance_base + 1``, ...
    -- the order and base a :class:`~sitl.firmware.FirmwareFleet` must use, which
    :meth:`firmware_vehicles` gives. Positions are metres north/east of ``origin`` (lat, lon,
    AMSL alt of the ground). ``firmware``: who flies it; for PX4, ``speed`` is the pace of the
    world's clock (times real time: the fleet's speed factor), which the world sets for PX4."""

    def __init__(self, origin: tuple[float, float, float], *, instance_base: int = 20,
                 host: str = "127.0.0.1", firmware: Firmware = "ardupilot", speed: float = 1.0) -> None:
        self.origin = origin
        self.instance_base = instance_base
        self.host = host
        self.firmware = firmware
        self.speed = speed
        self.world = World()
        self._sysids: dict[str, tuple[int, Mapping[str, float]]] = {}
        self.server: JsonServer | Px4HilServer | None = None

    def _next_instance(self) -> int:
        return self.instance_base + len(self.world.vehicles)

    def add_carrier(self, name: str, sysid: int, *, north: float = 0.0, east: float = 0.0,
                    yaw_deg: float = 0.0, deck: Deck | None = None, params: GroundParams | None = None,
                    firmware_params: Mapping[str, float] | None = None) -> None:
        """A ground vehicle (ArduRover, PX4's Ackermann rover) with a deck (``Deck()`` unless given)."""
        default = PX4_ROVER if self.firmware == "px4" else None
        self.world.add_ground_vehicle(name, self._next_instance(), north=north, east=east,
                                      yaw=math.radians(yaw_deg), deck=deck or Deck(),
                                      params=params or default)
        self._sysids[name] = (sysid, firmware_params or {})

    def add_copter(self, name: str, sysid: int, *, north: float = 0.0, east: float = 0.0,
                   yaw_deg: float = 0.0, on_deck_of: str | None = None, params: QuadParams | None = None,
                   firmware_params: Mapping[str, float] | None = None) -> None:
        """A quad (ArduCopter, PX4's quad X) on the ground at (north, east), or on a carrier's deck
        at that offset (forward, right) from the carrier."""
        default = PX4_QUAD if self.firmware == "px4" else None
        self.world.add_copter(name, self._next_instance(), north=north, east=east,
                              yaw=math.radians(yaw_deg), on_deck_of=on_deck_of, params=params or default)
        self._sysids[name] = (sysid, firmware_params or {})

    def home(self, name: str) -> tuple[float, float, float, float]:
        """The firmware ``--home`` (lat, lon, AMSL alt, heading degrees) of a vehicle's start."""
        v = self.world.vehicles[name]
        lat, lon, alt = offset(self.origin, *v.start)
        return (lat, lon, alt, math.degrees(v.start_yaw) % 360.0)

    def firmware_vehicles(self) -> list[FirmwareVehicle]:
        """The vehicles for a ``FirmwareFleet(..., instance_base=self.instance_base)``, in order."""
        out = []
        for name, v in self.world.vehicles.items():
            sysid, params = self._sysids[name]
            frame: Frame = "rover" if isinstance(v.model, GroundVehicle) else "copter"
            model = PX4_SIMULATOR if self.firmware == "px4" else "JSON"
            out.append(FirmwareVehicle(name, sysid, frame, self.home(name), dict(params), model=model))
        return out

    # -- running ----------------------------------------------------------------------------
    def start(self) -> JsonWorld:
        if self.firmware == "px4":
            self.server = Px4HilServer(self.world, self.origin, host=self.host, speed=self.speed).start()
        else:
            self.server = JsonServer(self.world, self.host).start()
        return self

    def stop(self) -> None:
        if self.server is not None:
            self.server.stop()
            self.server = None

    def __enter__(self) -> JsonWorld:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # -- reading (thread-safe) ---------------------------------------------------------------
    def state(self, name: str) -> Body:
        """A copy of a vehicle's state (world NED from the origin)."""
        v = self.world.vehicles[name]
        with self._lock():
            b = v.body
            return Body(b.position, b.velocity, b.attitude, b.gyro, b.accel_body)

    def on_deck(self, name: str) -> str | None:
        with self._lock():
            return self.world.on_deck(name)

    def stats(self, name: str) -> LinkStats | HilStats:
        assert self.server is not None
        return self.server.stats[name]

    def _lock(self) -> AbstractContextManager[object]:
        return self.server.lock if self.server is not None else nullcontext()
