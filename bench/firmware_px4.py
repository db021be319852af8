"""Flown vs planned on real PX4 firmware (SITL with SIH physics): deploy then collect, several times.

One PX4 fleet (an Ackermann rover carrier, three quadcopters at its home: ``tests/firmware/px4_fleet``)
is started; ``fleetctl deploy`` and ``fleetctl collect`` are flown through the command line at the
firmware's speed factor, ``--rounds`` times in a row; after a round that is not complete (a rover
left beside the carrier, where the next deployment would not launch it) the next round flies a
fresh fleet. For each command the table gives the
summaries' ``makespan_planned`` and ``makespan_flown`` (mission seconds: fleetctl's clock, which
follows the carrier's own time on SITL firmware) and the flown makespan in the carrier's own
seconds measured apart (its ``time_boot_ms`` in the run's ``traffic.tlog`` from the journal record
the makespan starts at to the one it ends at: the last task reached, the park command).

    FLEETCTL_PX4_DIR=/path/to/px4 python bench/firmware_px4.py [--rounds 3] [--seed S] [--json OUT]

``--seed S``: round k flies tasks drawn at random with seed S + k (15-30 m away, 3-10 m up: the
firmware tests' random missions) instead of the fixed three tasks.

``--deck``: the same airframes fly on ``sitl.json_physics`` (PX4's simulator interface) instead of
SIH, the quadcopters riding on the carrier's deck (``px4_fleet.px4_deck_fleet``), at 2x.

Prints a markdown table. Each round takes about 30 s of wall time on a quiet machine.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from pymavlink import mavutil

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT / "tests" / "firmware"))

from px4_fleet import (  # noqa: E402
    DECK,
    DECK_SPEEDUP,
    SPEEDUP,
    TASKS,
    mission_yaml,
    port_free,
    px4_deck_fleet,
    px4_fleet,
    random_task_positions,
)

STARTS = ("carrier_started", "collection_started")  # the journal record a command's makespan counts from


def end_of(rows: list[dict[str, Any]]) -> float | None:
    """The wall time (unix) a command's flown makespan ends at: a deployment's last task reached, a
    complete collection's park command (sent as soon as its last stop's loading is over)."""
    ends = [r["t"] for r in rows if r["kind"] == "task_reached"
            or (r["kind"] == "command" and r.get("command") == "hold_and_disarm")]
    return ends[-1] if ends else None


def fleetctl(mission: Path, runs: Path, *args: str, speedup: float = SPEEDUP,
             timeout: float = 240.0) -> subprocess.CompletedProcess[str]:
    argv = [sys.executable, "-m", "fleetctl.cli", *args, "-m", str(mission), "--speedup", f"{speedup:g}"]
    if args[0] != "status":
        argv += ["--yes", "--headless", "--runs", str(runs)]
    return subprocess.run(argv, cwd=ROOT, capture_output=True, text=True, timeout=timeout, check=False)


def wait_ready(mission: Path, runs: Path, speedup: float, timeout: float = 60.0) -> None:
    deadline = time.monotonic() + timeout
    while fleetctl(mission, runs, "status", "--timeout", "10", speedup=speedup).returncode != 0:
        if time.monotonic() > deadline:
            raise RuntimeError("the PX4 fleet was not ready")
        time.sleep(1.0)


TAIL = 0.5  # wall s: an end this soon after the carrier's last position report is timed on from it


def vehicle_seconds(run_dir: Path, start: float, end: float, sysid: int = 1) -> float | None:
    """The vehicle's own seconds (``time_boot_ms`` of its GLOBAL_POSITION_INT) between two wall
    times (unix), interpolated; None without its telemetry."""
    log = mavutil.mavlink_connection(str(run_dir / "traffic.tlog"), dialect="ardupilotmega")
    pts: list[tuple[float, float]] = []
    while (msg := log.recv_match(type="GLOBAL_POSITION_INT", blocking=False)) is not None:
        if msg.get_srcSystem() == sysid:
            pts.append((msg._timestamp, msg.time_boot_ms / 1000.0))

    def at(t: float) -> float | None:
        for (t0, b0), (t1, b1) in zip(pts, pts[1:], strict=False):
            if t0 <= t <= t1:
                return b0 + (b1 - b0) * (t - t0) / max(t1 - t0, 1e-9)
        if len(pts) >= 2 and 0.0 < t - pts[-1][0] <= TAIL:  # the run ended just after its last report
            (t0, b0), (t1, b1) = pts[-2], pts[-1]
            return b1 + (b1 - b0) * (t - t1) / max(t1 - t0, 1e-9)
        return None

    a, b = at(start), at(end)
    return None if a is None or b is None else b - a


def fly(mission: Path, runs: Path, command: str, speedup: float) -> dict[str, Any]:
    out = runs / f"{command}-{time.monotonic_ns()}.json"
    proc = fleetctl(mission, runs, command, "--summary", str(out), speedup=speedup)
    s = json.loads(out.read_text()) if out.exists() else {}
    row: dict[str, Any] = {"command": command, "exit": proc.returncode, "result": s.get("result"),
                           "planned": s.get("makespan_planned"), "flown": s.get("makespan_flown"),
                           "vehicle": None}
    if s.get("journal") and s.get("makespan_flown") is not None:
        run_dir = Path(s["journal"]).parent
        rows = [json.loads(line) for line in (run_dir / "journal.jsonl").read_text().splitlines() if line]
        start = next((r["t"] for r in rows if r["kind"] in STARTS), None)
        end = end_of(rows)
        if start is not None and end is not None:
            row["vehicle"] = vehicle_seconds(run_dir, start, end)
    return row


def percent(planned: float | None, flown: float | None) -> str:
    return "-" if not planned or flown is None else f"{100.0 * (flown - planned) / planned:+.1f} %"


def fly_rounds(mission: Path, runs: Path, k: int, args: argparse.Namespace,
               rows: list[dict[str, Any]]) -> int:
    """Fly rounds k, k + 1, ... on one fleet, until one is not complete (then its vehicles may not
    be where the next round needs them: a rover beside the carrier) or all are flown; return the
    number of rounds flown in all."""
    while k < args.rounds:
        tasks = TASKS if args.seed is None else random_task_positions(args.seed + k)
        mission.write_text(mission_yaml(tasks, deck_height=DECK.height if args.deck else None))
        k += 1
        for command in ("deploy", "collect"):
            r = fly(mission, runs, command, DECK_SPEEDUP if args.deck else SPEEDUP)
            r["round"] = k
            rows.append(r)
            p, f, v = r["planned"], r["flown"], r["vehicle"]
            cells = [f"{x:.1f}" if x is not None else "-" for x in (p, f, v)]
            print(f"| {k} | {command} | {r['result']} | {cells[0]} | {cells[1]} | {percent(p, f)} | "
                  f"{cells[2]} | {percent(p, v)} |", flush=True)
            if r["result"] != "complete":
                return k
    return k


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=3, help="deploy + collect this many times (default 3)")
    ap.add_argument("--json", help="also write the rows here")
    ap.add_argument("--runs", help="keep the run folders here (default: a temporary folder)")
    ap.add_argument("--seed", type=int,
                    help="round k flies random tasks of seed SEED + k (default: fixed tasks)")
    ap.add_argument("--deck", action="store_true",
                    help="fly on sitl.json_physics with the carrier's deck instead of PX4's SIH")
    args = ap.parse_args()
    if not port_free():
        print("UDP port 14550 (PX4's ground-station port) is in use", file=sys.stderr)
        return 2
    rows: list[dict[str, Any]] = []
    print("| round | command | result | planned s | flown s (mission) | vs planned | flown s (vehicle) "
          "| vs planned |")
    print("|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        runs = Path(args.runs or Path(tmp) / "runs").absolute()  # fleetctl runs in the repository
        runs.mkdir(parents=True, exist_ok=True)
        # kept runs keep their mission beside them (bench/firmware_stops.py reads its origin)
        mission = (runs if args.runs else Path(tmp)) / "mission.yaml"
        k = 0
        while k < args.rounds:  # a fleet per stretch of complete rounds
            speedup = DECK_SPEEDUP if args.deck else SPEEDUP
            with px4_deck_fleet() if args.deck else px4_fleet(speedup=SPEEDUP):
                mission.write_text(mission_yaml(deck_height=DECK.height if args.deck else None))
                wait_ready(mission, runs, speedup)
                k = fly_rounds(mission, runs, k, args, rows)
            if k < args.rounds:
                print(f"| {k} | - | the next round flies a fresh PX4 fleet | | | | | |", flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
