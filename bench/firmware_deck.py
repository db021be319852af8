"""Several carrier stops on real ArduPilot firmware with the marsupial deck (``sitl.json_physics``):
random missions fleetctl has never seen, flown through the command line.

For each seed, four tasks in two groups (``tests/firmware/deck_team.random_groups``: group a
35-55 m from the carrier, group b 60-80 m beyond it, 3-8 m up) and the deck test's mission
(``rovers.deploy_range`` 25 m, ``endurance_range`` 100 m, carrier 3 m/s): an ArduRover carrier
and four ArduCopter rovers on its deck start on one physics world; ``fleetctl deploy`` flies, the
rovers land where they are, ``fleetctl collect`` flies. The table gives each command's result,
its plan's carrier stops, planned and flown makespans (mission seconds), how far the rovers ended
from their tasks (the physics' positions) and how many came down on the deck.

    FLEETCTL_ARDUPILOT_DIR=/path/to/ardupilot python bench/firmware_deck.py [--seeds 1,2,3] \
        [--json OUT] [--runs DIR]
    FLEETCTL_PX4_DIR=/path/to/px4 python bench/firmware_deck.py --px4 [--seeds 1,2,3] ...

``--px4``: PX4's Ackermann rover carrier and four PX4 quadcopters fly the same missions on the
world through PX4's simulator interface (``tests/firmware/px4_fleet.px4_deck_fleet``, 2x; the
ground-station port is PX4's 14550).

About 70 s of wall time per seed on 2 cores (boot to armable included). Lockstep firmware that
falls behind on a loaded machine makes flights look longer: run it on a quiet machine.
"""

from __future__ import annotations

import contextlib
import json
import math
import sys
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests" / "firmware"))

from ardupilot_team import horizontal, land_where_they_are  # noqa: E402
from deck_team import Rides, deck_mission, deck_team, ne_to_enu, plan_stops, random_groups  # noqa: E402
from firmware import fly_seeds, percent, seed_args, seed_folder  # noqa: E402  (bench/firmware.py)
from px4_fleet import DECK, DECK_SPEEDUP, GCS_PORT, cli, mission_yaml, px4_deck_fleet, wait_ready  # noqa: E402


def _cell(proc: Any, summary: dict[str, Any]) -> dict[str, Any]:
    return {"exit": proc.returncode, "result": summary.get("result"),
            "stops": plan_stops(summary) if summary.get("journal") else None,
            "planned": summary.get("makespan_planned"), "flown": summary.get("makespan_flown")}


def fly_seed(seed: int, port: int, instance_base: int, keep: Path | None = None) -> dict[str, Any]:
    """Deploy then collect seed ``seed``'s tasks on the deck; ``keep``: the team's folder goes to
    ``keep/seed-<seed>`` instead of a temporary folder."""
    tasks = random_groups(seed)
    row: dict[str, Any] = {"seed": seed, "tasks": tasks}
    with contextlib.ExitStack() as stack:
        folder = seed_folder(stack, seed, keep)
        team, world = stack.enter_context(deck_team(folder, 4, deck_mission(4, tasks, port),
                                                    gcs_port=port, instance_base=instance_base))
        proc, deploy = team.fly("deploy", timeout=400)
        row["deploy"] = _cell(proc, deploy)
        where = dict(tasks)
        off = [horizontal(ne_to_enu(world.state(r).position), where[t])
               for t, r in deploy.get("assignment", {}).items()]
        row["deploy"]["off_task_m"] = max(off) if off else None
        if deploy.get("result") != "complete":
            return row
        land_where_they_are(port, [11 + k for k in range(len(team.rovers))])
        with Rides(world, team.rovers) as rides:
            proc, collect = team.fly("collect", timeout=400)
        row["collect"] = _cell(proc, collect)
        row["collect"]["on_deck"] = sum(world.on_deck(r) == "carrier" for r in team.rovers)
        row["collect"]["boarded"] = len(rides.boarded)
    return row


def fly_seed_px4(seed: int, port: int, instance_base: int, keep: Path | None = None) -> dict[str, Any]:
    """:func:`fly_seed` with PX4 (``port`` is PX4's 14550 whatever is asked)."""
    tasks = random_groups(seed)
    row: dict[str, Any] = {"seed": seed, "tasks": tasks}
    with contextlib.ExitStack() as stack:
        folder = seed_folder(stack, seed, keep)
        mission = folder / "mission.yaml"
        mission.write_text(mission_yaml([(t, *p) for t, p in tasks], n_rovers=4, deploy_range=25.0,
                                        endurance_range=100.0, deck_height=DECK.height))
        _fleet, world = stack.enter_context(px4_deck_fleet(n_rovers=4, instance_base=instance_base))
        rovers = [f"r{k + 1}" for k in range(4)]
        if wait_ready(mission, timeout=60.0).returncode != 0:
            row["deploy"] = dict.fromkeys(("exit", "stops", "planned", "flown")) | {"result": "not ready"}
            return row

        def fly(command: str) -> dict[str, Any]:
            out = folder / f"{command}.json"
            proc = cli(command, "-m", str(mission), "--yes", "--headless", "--speedup", f"{DECK_SPEEDUP:g}",
                       "--summary", str(out), "--runs", str(folder / "runs"), timeout=400.0)
            return _cell(proc, json.loads(out.read_text()) if out.exists() else {})

        row["deploy"] = fly("deploy")
        where = dict(tasks)
        summary = folder / "deploy.json"
        s = json.loads(summary.read_text()) if summary.exists() else {}
        off = [horizontal(ne_to_enu(world.state(r).position), where[t])
               for t, r in s.get("assignment", {}).items()]
        row["deploy"]["off_task_m"] = max(off) if off else None
        if row["deploy"]["result"] != "complete":
            return row
        land_where_they_are(GCS_PORT, [11 + k for k in range(4)])
        with Rides(world, rovers) as rides:
            row["collect"] = fly("collect")
        row["collect"]["on_deck"] = sum(world.on_deck(r) == "carrier" for r in rovers)
        row["collect"]["boarded"] = len(rides.boarded)
    return row


def main() -> int:
    columns = ("seed", "deploy", "stops", "planned s", "flown s", "flown vs planned",
               "farthest from its task m", "collect", "stops", "planned s", "flown s", "flown vs planned",
               "on the deck")
    args = seed_args(__doc__, 14650, 70, flags=[("--px4", "fly PX4 instead of ArduPilot")])
    return fly_seeds(args, fly_seed_px4 if args.px4 else fly_seed, columns, _line)


def _line(r: dict[str, Any]) -> str:
    d, c, nan = r["deploy"], r.get("collect", {}), math.nan
    return (f"| {r['seed']} | {d['result']} | {d['stops']} | {d['planned'] or nan:.1f} "
            f"| {d['flown'] or nan:.1f} | {percent(d)} | {d['off_task_m'] or nan:.1f} "
            f"| {c.get('result', '-')} | {c.get('stops', '-')} | {c.get('planned') or nan:.1f} "
            f"| {c.get('flown') or nan:.1f} | {percent(c)} | {c.get('on_deck', '-')} of 4 |")


if __name__ == "__main__":
    sys.exit(main())
