"""sitl - a simulated marsupial fleet (one or several carriers, many rovers) speaking real MAVLink 2 over UDP.

Public API (sitl depends on neither the controller nor the planners)::

    from sitl import FleetConfig, SimFleet, Fault, serve, run_forever

    config = FleetConfig.from_mission_dict(yaml.safe_load(open("missions/x.yaml")), speedup=5.0)
    async with SimFleet(config) as fleet:
        fleet.endpoints            # {vehicle_id: "udp://127.0.0.1:PORT" | the udpin:// URL}
        fleet.sim_time             # simulated seconds
        fleet.rover("r1").position # ENU metres; .loaded, .battery (0..1), .on_ground, .flown
        fleet.body("carrier").position, fleet.world.loaded_rovers()  # on any deck, or loaded_rovers("c2")
        fleet.vehicle("r1").armed, .mode (sitl.Mode), .mission, .current, .finished, .statustexts
        fleet.snapshot()           # plain dict of every vehicle's state
        fleet.inject(Fault("dropout", vehicle="r3", at=20.0, until=45.0))
        fleet.set_packet_loss(0.2) ; fleet.set_latency(0.1, vehicle="r1") ; fleet.dropout("r2", 10.0)
        fleet.clear_faults()
        fleet.link_stats()         # rx/tx counters incl. malformed datagrams
        await fleet.wait_for(lambda: fleet.rover("r1").loaded, timeout=10)

    serve(config)                  # blocking, until Ctrl-C / SIGTERM
    await run_forever(config, on_ready=callback, stop=event)

    python -m sitl --mission FILE [--speedup X] [--autopilot px4|ardupilot] [--seed N]

Connection URLs are the controller's side (``sim``, ``udp://``/``udpout://`` = the controller
sends, the fleet binds; ``udpin://`` = the controller listens, the fleet sends there). Rovers
without their own connection share their carrier's endpoint (told apart by system id).
Several carriers: ``FleetConfig.more_carriers`` holds the others and ``VehicleSpec.carrier`` names the
deck a rover starts on; a rover touching down by any stopped carrier is loaded on that one.
Physics and fault times are simulated seconds; telemetry rates, protocol timeouts and latency
are wall seconds.
"""

from .config import ConfigError, FleetConfig, VehicleSpec
from .endpoint import LinkError
from .faults import Fault, FaultError
from .flavour import Mode
from .fleet import SimFleet, run_forever, serve
from .vehicle import SimVehicle
from .world import LOAD_RADIUS, Carrier, Phase, Rover, World

__all__ = [
    "LOAD_RADIUS",
    "Carrier",
    "ConfigError",
    "Fault",
    "FaultError",
    "FleetConfig",
    "LinkError",
    "Mode",
    "Phase",
    "Rover",
    "SimFleet",
    "SimVehicle",
    "VehicleSpec",
    "World",
    "run_forever",
    "serve",
]
