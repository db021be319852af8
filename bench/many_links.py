"""More than 255 vehicles in one controller: ``--carriers`` carriers, each on a simulated link of
its own with ``--rovers`` rovers, every link numbering its vehicles with the same system ids
(carrier 1, rovers 2..N+1). The mission is flown end to end through
:func:`fleetctl.run.flight.execute` (``deploy`` by default) on the embedded simulated fleet, over
real MAVLink/UDP: the controller shares the tasks between the teams, connects every vehicle,
uploads, arms and launches. The simulated fleet runs in the same process, so the CPU column is
the controller's and the simulator's together.

    python bench/many_links.py [--carriers 4] [--rovers 100] [--tasks 80] [--speedup 10] [--command deploy]

Prints a markdown table: vehicles, links, result, tasks reached, planned and flown makespan,
wall time and process CPU; exits 1 when the run did not complete.
"""

from __future__ import annotations

import argparse
import asyncio
import math
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import yaml

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from fleetctl.journal import read_journal  # noqa: E402
from fleetctl.mission import load_mission  # noqa: E402
from fleetctl.mission.links import vehicle_links  # noqa: E402
from fleetctl.run.flight import execute  # noqa: E402

ORIGIN = {"lat": 47.397742, "lon": 8.545594, "alt": 488.0}
SPACING = 300.0  # m between two carriers' starts


def mission(carriers: int, rovers: int, tasks: int) -> dict[str, Any]:
    """``carriers`` teams on links of their own, the same system ids on each, ``tasks`` tasks spread
    over a ring around each carrier's start."""
    teams = [{"id": f"c{k + 1}", "sysid": 1, "connection": "sim", "position": [k * SPACING, 0.0],
              "heading_deg": 0, "max_speed": 15.0, "accel": 10.0, "turn_rate": None, "unload_time": 1.0,
              "load_time": 1.0, "fleet": {"count": rovers, "sysid_start": 2}} for k in range(carriers)]
    spots = []
    for j in range(tasks):
        k = j % carriers
        a = 2 * math.pi * (j // carriers) / max(1, math.ceil(tasks / carriers))
        spots.append({"id": f"t{j + 1}", "position": [k * SPACING + 60 * math.cos(a), 80 + 60 * math.sin(a),
                                                      4.0]})
    return {"name": "many_links", "origin": ORIGIN, "carriers": teams,
            "rovers": {"max_speed": 5.0, "accel": None, "deploy_range": 60.0, "endurance_range": 2000.0,
                       "reserve": 0.1},
            "tasks": spots, "sim": {"speedup": 10.0, "faults": []},
            "links": {"heartbeat_timeout": 5.0}, "dwell": 2.0}


async def fly(args: argparse.Namespace, folder: Path) -> dict[str, Any]:
    path = folder / "many_links.yaml"
    path.write_text(yaml.safe_dump(mission(args.carriers, args.rovers, args.tasks), sort_keys=False))
    m = load_mission(path)
    links = vehicle_links(m)
    c0, w0 = time.process_time(), time.monotonic()
    out = await execute(m, args.command, run_dir=folder / "run", speedup=args.speedup, connect_timeout=60.0)
    cpu, wall = time.process_time() - c0, time.monotonic() - w0
    s = out.summary
    records = read_journal(folder / "run" / "journal.jsonl")
    connected = {r["vehicle"]: (r["url"], r["sysid"]) for r in records if r["kind"] == "connected"}
    assert len(set(connected.values())) == len(connected), "two vehicles on one (link, sysid)"
    return {"vehicles": len(links), "links": len(set(links.values())), "connected": len(connected),
            "sysids": len({sysid for _, sysid in connected.values()}), "result": s["result"],
            "reached": len(s.get("tasks_reached", [])), "tasks": args.tasks,
            "planned": s.get("makespan_planned"), "flown": s.get("makespan_flown"), "wall": wall, "cpu": cpu,
            "exit": out.exit_code}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--carriers", type=int, default=4)
    ap.add_argument("--rovers", type=int, default=100, help="rovers per carrier (sysids 2..N+1 on each link)")
    ap.add_argument("--tasks", type=int, default=80)
    ap.add_argument("--speedup", type=float, default=10.0)
    ap.add_argument("--command", default="deploy", choices=("deploy", "run"))
    ap.add_argument("--keep", type=Path, default=None, help="write the mission and run folder here")
    args = ap.parse_args()
    if args.keep is not None:
        args.keep.mkdir(parents=True, exist_ok=True)
        r = asyncio.run(fly(args, args.keep))
    else:
        with tempfile.TemporaryDirectory() as tmp:
            r = asyncio.run(fly(args, Path(tmp)))
    print(f"python {sys.version.split()[0]}, {args.command}, speedup {args.speedup:g}\n")
    print("| vehicles | links | connected | distinct sysids | result | tasks reached | makespan planned s "
          "| flown s | wall s | CPU s |")
    print("|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|")
    print(f"| {r['vehicles']} | {r['links']} | {r['connected']} | {r['sysids']} | {r['result']} | "
          f"{r['reached']}/{r['tasks']} | {r['planned']} | {r['flown']} | {r['wall']:.1f} | {r['cpu']:.1f} |")
    sys.exit(0 if r["exit"] == 0 else 1)


if __name__ == "__main__":
    main()
