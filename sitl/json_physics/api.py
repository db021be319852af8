"""JsonWorld: a world of vehicles, its UDP server, and the firmware vehicles that fly on it."""

from __future__ import annotations

import math
from collections.abc import Mapping
from contextlib import AbstractContextManager, nullcontext

from ..firmware import FirmwareVehicle, Frame
from .body import Body
from .ground_vehicle import GroundParams, GroundVehicle
from .multicopter import QuadParams
from .server import JsonServer, LinkStats
from .world import Deck, World

EARTH_RADIUS = 6378137.0  # m, as ArduPilot's Location offsets


class JsonWorld:
    """Vehicles added in order get instance numbers ``instance_base``, ``instance_base + 1``, ...
    -- the order and base a :class:`~sitl.firmware.FirmwareFleet` must use, which
    :meth:`firmware_vehicles` gives. Positions are metres north/east of ``origin`` (lat, lon,
    AMSL alt of the ground)."""

    def __init__(self, origin: tuple[float, float, float], *, instance_base: int = 20,
                 host: str = "127.0.0.1") -> None:
        self.origin = origin
        self.instance_base = instance_base
        self.host = host
        self.world = World()
        self._sysids: dict[str, tuple[int, Mapping[str, float]]] = {}
        self.server: JsonServer | None = None

    def _next_instance(self) -> int:
        return self.instance_base + len(self.world.vehicles)

    def add_carrier(self, name: str, sysid: int, *, north: float = 0.0, east: float = 0.0,
                    yaw_deg: float = 0.0, deck: Deck | None = None, params: GroundParams | None = None,
                    firmware_params: Mapping[str, float] | None = None) -> None:
        """A ground vehicle (ArduRover) with a deck (``Deck()`` unless given)."""
        self.world.add_ground_vehicle(name, self._next_instance(), north=north, east=east,
                                      yaw=math.radians(yaw_deg), deck=deck or Deck(), params=params)
        self._sysids[name] = (sysid, firmware_params or {})

    def add_copter(self, name: str, sysid: int, *, north: float = 0.0, east: float = 0.0,
                   yaw_deg: float = 0.0, on_deck_of: str | None = None, params: QuadParams | None = None,
                   firmware_params: Mapping[str, float] | None = None) -> None:
        """A quad (ArduCopter) on the ground at (north, east), or on a carrier's deck at that
        offset (forward, right) from the carrier."""
        self.world.add_copter(name, self._next_instance(), north=north, east=east,
                              yaw=math.radians(yaw_deg), on_deck_of=on_deck_of, params=params)
        self._sysids[name] = (sysid, firmware_params or {})

    def home(self, name: str) -> tuple[float, float, float, float]:
        """The firmware ``--home`` (lat, lon, AMSL alt, heading degrees) of a vehicle's start."""
        v = self.world.vehicles[name]
        lat0, lon0, alt0 = self.origin
        n, e, d = v.start
        lat = lat0 + math.degrees(n / EARTH_RADIUS)
        lon = lon0 + math.degrees(e / (EARTH_RADIUS * math.cos(math.radians(lat0))))
        return (lat, lon, alt0 - d, math.degrees(v.start_yaw) % 360.0)

    def firmware_vehicles(self) -> list[FirmwareVehicle]:
        """The vehicles for a ``FirmwareFleet(..., instance_base=self.instance_base)``, in order."""
        out = []
        for name, v in self.world.vehicles.items():
            sysid, params = self._sysids[name]
            frame: Frame = "rover" if isinstance(v.model, GroundVehicle) else "copter"
            out.append(FirmwareVehicle(name, sysid, frame, self.home(name), dict(params), model="JSON"))
        return out

    # -- running ----------------------------------------------------------------------------
    def start(self) -> JsonWorld:
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

    def stats(self, name: str) -> LinkStats:
        assert self.server is not None
        return self.server.stats[name]

    def _lock(self) -> AbstractContextManager[object]:
        return self.server.lock if self.server is not None else nullcontext()
