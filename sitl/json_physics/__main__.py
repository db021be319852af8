"""``python -m sitl.json_physics``: serve a world's physics until Ctrl-C / SIGTERM, to ArduPilot
(``--model JSON``) or PX4 (``PX4_SIMULATOR=rotorpy``) firmware."""

from __future__ import annotations

import argparse
import math
import signal
import threading
from collections.abc import Sequence

from .api import PX4_QUAD, PX4_ROVER, PX4_SIMULATOR, JsonWorld
from .px4_hil import hil_port
from .world import Deck


def _vehicle(text: str) -> tuple[str, int, float, float, float, str | None]:
    """NAME=INSTANCE[,NORTH,EAST[,YAW_DEG]][@CARRIER]"""
    spec, _, carrier = text.partition("@")
    name, _, rest = spec.partition("=")
    fields = rest.split(",")
    if not name or not fields[0] or len(fields) not in (1, 3, 4):
        raise argparse.ArgumentTypeError(f"expected NAME=INSTANCE[,NORTH,EAST[,YAW_DEG]][@CARRIER]: {text}")
    nums = [float(f) for f in fields[1:]] + [0.0] * (4 - len(fields))
    return name, int(fields[0]), nums[0], nums[1], nums[2], carrier or None


def main(argv: Sequence[str] | None = None) -> None:
    ap = argparse.ArgumentParser(
        prog="python -m sitl.json_physics",
        description="Physics for ArduPilot SITL --model JSON or PX4 SITL's simulator interface: quads, "
                    "ground carriers and their decks. Each ArduPilot vehicle listens on UDP 9002 + 10 * "
                    "INSTANCE, each PX4 one on TCP 4560 + INSTANCE. Positions are metres north/east "
                    "of --origin (for a copter on a deck: forward/right of the carrier).")
    ap.add_argument("--origin", required=True, help="LAT,LON,ALT (AMSL m) of the ground at north=east=0")
    ap.add_argument("--carrier", action="append", default=[], type=_vehicle,
                    metavar="NAME=INSTANCE[,N,E[,YAW]]", help="an ArduRover ground vehicle with a deck")
    ap.add_argument("--copter", action="append", default=[], type=_vehicle,
                    metavar="NAME=INSTANCE[,N,E[,YAW]][@CARRIER]", help="an ArduCopter quad (+ frame)")
    ap.add_argument("--deck-height", type=float, default=0.5)
    ap.add_argument("--deck-radius", type=float, default=1.5)
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--firmware", choices=("ardupilot", "px4"), default="ardupilot",
                    help="who flies the world (default ardupilot)")
    ap.add_argument("--speed", type=float, default=1.0,
                    help="PX4: the world's clock in times real time (PX4_SIM_SPEED_FACTOR; default 1)")
    args = ap.parse_args(argv)
    lat, lon, alt = (float(x) for x in args.origin.split(","))
    px4 = args.firmware == "px4"
    world = JsonWorld((lat, lon, alt), host=args.host, firmware=args.firmware, speed=args.speed)
    deck = Deck(args.deck_height, args.deck_radius)
    for name, inst, n, e, yaw, _ in args.carrier:
        world.world.add_ground_vehicle(name, inst, north=n, east=e, yaw=math.radians(yaw), deck=deck,
                                       params=PX4_ROVER if px4 else None)
    for name, inst, n, e, yaw, carrier in args.copter:
        world.world.add_copter(name, inst, north=n, east=e, yaw=math.radians(yaw), on_deck_of=carrier,
                               params=PX4_QUAD if px4 else None)
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    with world:
        carriers = {c[0] for c in args.carrier}
        for name, v in world.world.vehicles.items():
            h = world.home(name)
            if px4:
                airframe = 10045 if name in carriers else 10040
                print(f"{name}: TCP {hil_port(v.instance)}; start with PX4_SYS_AUTOSTART={airframe} "
                      f"PX4_SIMULATOR={PX4_SIMULATOR} PX4_SIM_SPEED_FACTOR={args.speed:g} "
                      f"bin/px4 -i {v.instance} -d -w WORKDIR ABS/PATH/etc", flush=True)
                continue
            kind = "ardurover" if name in carriers else "arducopter"
            print(f"{name}: UDP {world.server.ports[name] if world.server else '?'}; start with {kind} "
                  f"--model JSON --instance {v.instance} --home {h[0]:.7f},{h[1]:.7f},{h[2]:.2f},{h[3]:g}",
                  flush=True)
        try:
            stop.wait()
        except KeyboardInterrupt:
            pass


if __name__ == "__main__":
    main()
