"""Physics for ArduPilot's JSON SITL interface (``--model JSON``) and PX4's simulator interface
(``simulator_mavlink``), with the marsupial deck.

Real ArduCopter and ArduRover firmware fly on physics computed here: a quadcopter in the ``+``
frame (:mod:`.multicopter`), a car-like ground vehicle (:mod:`.ground_vehicle`), and carriers'
decks on which copters ride (:mod:`.world`). All vehicles of one world live in one process, one
UDP port per firmware instance (:mod:`.server`, wire format :mod:`.protocol`)::

    from sitl.firmware import FirmwareFleet, find_ardupilot
    from sitl.json_physics import JsonWorld

    world = JsonWorld((47.397742, 8.545594, 488.0), instance_base=20)
    world.add_carrier("carrier", sysid=1)                       # ArduRover, deck 0.5 m high
    world.add_copter("r1", sysid=11, on_deck_of="carrier")      # ArduCopter on that deck
    with world, FirmwareFleet(find_ardupilot(), world.firmware_vehicles(), gcs_port=14620,
                              speedup=2, instance_base=world.instance_base) as fleet:
        ...                          # fly them over MAVLink at fleet.url
        world.state("r1").position   # NED metres from the origin; world.on_deck("r1") -> "carrier"

All vehicles share one clock: the server holds back a firmware that runs more than 20 ms
(simulated) ahead of the slowest one, so a copter riding a deck sees its carrier move smoothly
on its own clock (:mod:`.server`).

The firmware vehicles get ``--model JSON`` and a ``--home`` at their start position (for a copter
on a deck: the deck's height above the origin). Start the world before the firmware (it answers
the first servo packet) and use the same ``instance_base`` for both.

PX4 (its quadcopter X and Ackermann rover airframes, 10040 and 10045) flies the same world with
``JsonWorld(origin, firmware="px4", speed=S)``: the firmware connects to TCP ``4560 + instance``
and is sent its IMU and ground truth in lockstep (:mod:`.px4_hil`); ``firmware_vehicles()`` start
it with ``PX4_SIMULATOR=rotorpy`` (GPS, barometer and magnetometer simulated inside PX4).

From the command line (then start each firmware with ``--model JSON --instance I --home ...``
as printed)::

    python -m sitl.json_physics --origin 47.397742,8.545594,488 \\
        --carrier carrier=20 --copter r1=21@carrier --copter r2=22,10,5
"""

from .api import JsonWorld
from .body import Body
from .ground_vehicle import GroundParams, GroundVehicle
from .multicopter import Multicopter, QuadParams
from .px4_hil import Px4HilServer, hil_port
from .server import JsonServer, servo_port
from .world import Deck, World

__all__ = ["Body", "Deck", "GroundParams", "GroundVehicle", "JsonServer", "JsonWorld", "Multicopter",
           "Px4HilServer", "QuadParams", "World", "hil_port", "servo_port"]
