"""Flown vs planned on real ArduPilot firmware (SITL): random missions fleetctl has never seen.

For each seed an ArduRover carrier and three ArduCopter rovers (stock parameters, the firmware's
own physics, the rovers where the carrier starts) are started, ``fleetctl deploy`` then
``fleetctl collect`` are flown through the command line at the firmware's ``--speedup``, and the
summaries' ``makespan_planned`` / ``makespan_flown`` (mission seconds) are tabled. Tasks are drawn
as in ``tests/firmware`` (15-30 m from the carrier, 3-10 m up).

    FLEETCTL_ARDUPILOT_DIR=/path/to/ardupilot python bench/firmware.py [--seeds 1,2,3] [--json OUT] \
        [--runs DIR]

Prints a markdown table. Each seed takes about 35 s of wall time (boot to armable included).
Lockstep firmware that falls behind its --speedup on a loaded machine makes flights look longer:
run it on a quiet machine.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import shutil
import sys
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests" / "firmware"))

from ardupilot_team import ardupilot_team, mission_yaml, random_tasks  # noqa: E402


def seed_folder(stack: contextlib.ExitStack, seed: int, keep: Path | None) -> Path:
    """Where a seed's team runs: ``keep/seed-<seed>`` (emptied first), else a temporary folder
    that ``stack`` removes."""
    if keep is None:
        return Path(stack.enter_context(tempfile.TemporaryDirectory()))
    folder = keep / f"seed-{seed}"
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir(parents=True)
    return folder


def fly_seed(seed: int, port: int, instance_base: int, keep: Path | None = None) -> dict[str, Any]:
    """Deploy then collect seed ``seed``'s tasks; ``keep``: the team's folder (mission, run folders
    with their journals and tlogs) goes to ``keep/seed-<seed>`` instead of a temporary folder."""
    row: dict[str, Any] = {"seed": seed}
    with contextlib.ExitStack() as stack:
        folder = seed_folder(stack, seed, keep)
        team = stack.enter_context(ardupilot_team(folder, gcs_port=port, instance_base=instance_base,
                                                  mission=mission_yaml(port, 3, tasks=random_tasks(seed))))
        for command in ("deploy", "collect"):
            proc, summary = team.fly(command)
            row[command] = {"exit": proc.returncode, "result": summary.get("result"),
                            "planned": summary.get("makespan_planned"),
                            "flown": summary.get("makespan_flown")}
    return row


def percent(cell: dict[str, Any]) -> str:
    p, f = cell.get("planned"), cell.get("flown")
    return "-" if not p or f is None else f"{100.0 * (f - p) / p:+.1f} %"


def seed_args(doc: str, port: int, instance_base: int,
              flags: Sequence[tuple[str, str]] = ()) -> argparse.Namespace:
    """The command line of a bench that flies one firmware team per seed (this one and
    ``bench/firmware_deck.py``): seeds, ports, where the rows and the run folders go, and the
    bench's own on/off ``flags`` (name, help)."""
    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    for name, text in flags:
        ap.add_argument(name, action="store_true", help=text)
    ap.add_argument("--seeds", default="1,2,3", help="comma-separated task seeds (default 1,2,3)")
    ap.add_argument("--port", type=int, default=port, help=f"the ground-station UDP port (default {port})")
    ap.add_argument("--instance-base", type=int, default=instance_base,
                    help=f"first SITL instance number (each has its own ports; default {instance_base})")
    ap.add_argument("--json", help="also write the rows here")
    ap.add_argument("--runs", help="keep each seed's folder (its mission and run folders: journals, "
                    "plans, tlogs) here, as seed-N (default: a temporary folder; bench/firmware_stops.py "
                    "reads them)")
    return ap.parse_args()


def fly_seeds(args: argparse.Namespace, fly: Callable[[int, int, int, Path | None], dict[str, Any]],
              columns: Sequence[str], line: Callable[[dict[str, Any]], str]) -> int:
    """Fly every seed of ``args`` with ``fly``, print the table (``columns``, then each row's
    ``line`` as it comes), and write the rows to ``--json``."""
    print("| " + " | ".join(columns) + " |")
    print("|" + "---|" * len(columns))
    rows = []
    runs = Path(args.runs).absolute() if args.runs else None
    for seed in (int(s) for s in args.seeds.split(",")):
        rows.append(fly(seed, args.port, args.instance_base, runs))
        print(line(rows[-1]), flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))
    return 0


def _line(r: dict[str, Any]) -> str:
    d, c, nan = r["deploy"], r["collect"], float("nan")
    return (f"| {r['seed']} | {d['planned'] or nan:.1f} | {d['flown'] or nan:.1f} | {percent(d)} | "
            f"{c['planned'] or nan:.1f} | {c['flown'] or nan:.1f} | {percent(c)} |")


def main() -> int:
    columns = ("seed", "deploy planned s", "flown s", "flown vs planned", "collect planned s", "flown s",
               "flown vs planned")
    return fly_seeds(seed_args(__doc__, 14560, 80), fly_seed, columns, _line)


if __name__ == "__main__":
    sys.exit(main())
