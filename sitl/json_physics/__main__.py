"""``python -m sitl.json_physics``: serve a world's physics until Ctrl-C / SIGTERM."""

from __future__ import annotations

import argparse
import math
import signal
import threading
from collections.abc import Sequence

from .api import JsonWorld
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
        description="Physics for ArduPilot SITL --model JSON: quads, ground carriers and their decks. "
                    "Each vehicle listens on UDP 9002 + 10 * INSTANCE. Positions are metres north/east "
                    "of --origin (for a copter on a deck: forward/right of the carrier).")
    ap.add_argument("--origin", required=True, help="LAT,LON,ALT (AMSL m) of the ground at north=east=0")
    ap.add_argument("--carrier", action="append", default=[], type=_vehicle,
                    metavar="NAME=INSTANCE[,N,E[,YAW]]", help="an ArduRover ground vehicle with a deck")
    ap.add_argument("--copter", action="append", default=[], type=_vehicle,
                    metavar="NAME=INSTANCE[,N,E[,YAW]][@CARRIER]", help="an ArduCopter quad (+ frame)")
    ap.add_argument("--deck-height", type=float, default=0.5)
    ap.add_argument("--deck-radius", type=float, default=1.5)
    ap.add_argument("--host", default="127.0.0.1")
    args = ap.parse_args(argv)
    lat, lon, alt = (float(x) for x in args.origin.split(","))
    world = JsonWorld((lat, lon, alt), host=args.host)
    deck = Deck(args.deck_height, args.deck_radius)
    for name, inst, n, e, yaw, _ in args.carrier:
        world.world.add_ground_vehicle(name, inst, north=n, east=e, yaw=math.radians(yaw), deck=deck)
    for name, inst, n, e, yaw, carrier in args.copter:
        world.world.add_copter(name, inst, north=n, east=e, yaw=math.radians(yaw), on_deck_of=carrier)
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    with world:
        for name, v in world.world.vehicles.items():
            h = world.home(name)
            kind = "ardurover" if name in {c[0] for c in args.carrier} else "arducopter"
            print(f"{name}: UDP {world.server.ports[name] if world.server else '?'}; start with {kind} "
                  f"--model JSON --instance {v.instance} --home {h[0]:.7f},{h[1]:.7f},{h[2]:.2f},{h[3]:g}",
                  flush=True)
        try:
            stop.wait()
        except KeyboardInterrupt:
            pass


if __name__ == "__main__":
    main()
