"""``python -m sitl --mission FILE [--speedup X]``: serve a mission's simulated fleet until Ctrl-C."""

from __future__ import annotations

import argparse
import logging
import sys

import yaml

from .config import ConfigError, FleetConfig
from .endpoint import LinkError
from .fleet import SimFleet, serve


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m sitl", description=__doc__)
    ap.add_argument("--mission", required=True, help="mission YAML file")
    ap.add_argument("--speedup", type=float, default=None, help="simulated seconds per wall second")
    ap.add_argument("--autopilot", choices=("px4", "ardupilot"), default=None)
    ap.add_argument("--seed", type=int, default=None)
    ap.add_argument("-v", "--verbose", action="store_true", help="log every vehicle event")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        format="%(asctime)s %(name)s %(message)s")
    try:
        with open(args.mission, encoding="utf-8") as fh:
            data = yaml.safe_load(fh)
        config = FleetConfig.from_mission_dict(data, speedup=args.speedup, seed=args.seed,
                                               autopilot=args.autopilot)
    except (OSError, yaml.YAMLError) as exc:
        print(f"{args.mission}: cannot read the mission: {exc}", file=sys.stderr)
        return 2
    except ConfigError as exc:
        print(f"{args.mission}: {exc}", file=sys.stderr)
        return 2

    def ready(fleet: SimFleet) -> None:
        print(f"simulated fleet {config.name!r}: speedup {config.speedup:g}, autopilot {config.autopilot}")
        for spec in config.vehicles:
            print(f"  {spec.id:<12} sysid {spec.sysid:<3} {fleet.endpoints[spec.id]}")
        print("serving; Ctrl-C to stop", flush=True)

    try:
        serve(config, on_ready=ready)
    except LinkError as exc:
        print(f"{args.mission}: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
