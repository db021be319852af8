"""Where the carrier came to rest at its collection stops and where the rovers touched down, from
kept firmware runs (``bench/firmware.py --runs DIR``, ``bench/firmware_px4.py --runs DIR``).

For every collection run found under the given folders (a run folder holds ``journal.jsonl``,
``plan.json`` and the link's ``traffic.tlog``) and every stop of its plan, one row:

* the carrier's heading change into the stop (from the heading it stood at, or its previous leg;
  positive: a turn to the left, counter-clockwise), and the leg's length;
* where it came to rest: how far beyond the stop along its last leg, and how far across it, to the
  outside of its turn (negative: to the inside) - the median of its positions from the stop
  reached to its last rover loaded;
* how many of its rovers were moved over the carrier (journal: "over the carrier");
* how far from the carrier each rover touched the ground (its first position under 0.1 m after its
  last ``land`` command);
* the run's flown against planned makespan.

Run: ``python bench/firmware_stops.py DIR [DIR ...]`` (prints markdown; positions in the mission's
frame, ``fleetctl.geo``).
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fleetctl.geo import geodetic_to_enu  # noqa: E402
from fleetctl.mission.loader import load_mission  # noqa: E402

GROUND = 0.1  # m: a rover this low (above its home) has touched the ground
Track = list[tuple[float, float, float, float]]  # wall s, east, north, height


@dataclass
class Run:
    name: str
    folder: Path
    records: list[dict[str, Any]]
    plan: dict[str, Any]
    tracks: dict[int, Track]
    sysid: dict[str, int]


def collection_runs(folders: list[Path]) -> list[tuple[str, Path]]:
    """(name, folder) of the run folders under ``folders`` whose run was a collection; the name is
    the folder's path below the one given."""
    out = []
    for top in folders:
        for journal in sorted(top.rglob("journal.jsonl")):
            first = json.loads(journal.open().readline() or "{}")
            if first.get("kind") == "run" and first.get("command") == "collect":
                out.append((str(journal.parent.relative_to(top)), journal.parent))
    return out


def read_run(name: str, folder: Path) -> Run | None:
    """The journal, plan and positions of the run in ``folder`` (None without an origin or a tlog)."""
    from pymavlink import mavutil

    records = [json.loads(line) for line in (folder / "journal.jsonl").open()]
    # the mission the run flew, else one kept beside the run folders (its origin is what is needed)
    paths = [Path(records[0]["file"]), folder.parent / "mission.yaml", folder.parent.parent / "mission.yaml"]
    path = next((p for p in paths if p.exists()), None)
    if path is None:
        print(f"{name}: its mission file is gone ({records[0]['file']}): left out", file=sys.stderr)
        return None
    mission = load_mission(path)
    if mission.origin is None or not (folder / "traffic.tlog").exists():
        return None
    tracks: dict[int, Track] = {}
    log = mavutil.mavlink_connection(str(folder / "traffic.tlog"))
    while (msg := log.recv_match(type="GLOBAL_POSITION_INT", blocking=False)) is not None:
        e, n, _ = geodetic_to_enu(msg.lat / 1e7, msg.lon / 1e7, mission.origin.alt, mission.origin)
        tracks.setdefault(msg.get_srcSystem(), []).append((msg._timestamp, e, n, msg.relative_alt / 1e3))
    sysid = {r["vehicle"]: r["sysid"] for r in records if r["kind"] == "connected"}
    return Run(name, folder, records, json.loads((folder / "plan.json").read_text()), tracks, sysid)


def at(track: Track, t: float) -> tuple[float, float, float, float]:
    """The last position of ``track`` at or before wall time ``t`` (its first if none)."""
    before = [p for p in track if p[0] <= t]
    return before[-1] if before else track[0]


def wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def stop_rows(run: Run) -> list[dict[str, Any]]:
    """One row per stop of ``run``'s plan (the module docstring)."""
    recs, plan = run.records, run.plan
    carrier = run.tracks.get(run.sysid.get("carrier", -1), [])
    summary = next((r for r in recs if r["kind"] == "summary"), {})
    planned, flown = summary.get("makespan_planned"), summary.get("makespan_flown")
    pct = None if not planned or flown is None else 100.0 * (flown - planned) / planned
    heading = plan["carrier"]["heading"]
    rows = []
    for k, stop in enumerate(plan["stops"]):
        path = stop["carrier_path"]
        (x0, y0), (x1, y1) = path[0][:2], path[1][:2] if len(path) > 1 else path[0][:2]
        (xa, ya), (xb, yb) = path[-2][:2] if len(path) > 1 else path[0][:2], path[-1][:2]
        leg = sum(math.dist(a[:2], b[:2]) for a, b in zip(path, path[1:], strict=False))
        turn = wrap(math.atan2(y1 - y0, x1 - x0) - heading) if leg > 0 else 0.0
        heading = math.atan2(yb - ya, xb - xa) if leg > 0 else heading
        rovers = [leg_["rover"] for leg_ in stop["rovers"]]
        reached = next((r["t"] for r in recs if r["kind"] == "stop_reached" and r.get("stop") == k + 1), None)
        loaded = [r["t"] for r in recs if r["kind"] == "rover_loaded" and r.get("vehicle") in rovers]
        row: dict[str, Any] = {"run": run.name, "stop": k + 1, "turn": math.degrees(turn), "leg": leg,
                               "flown_pct": pct}
        if carrier and reached is not None and loaded:
            rest = [p for p in carrier if reached <= p[0] <= max(loaded)] or [at(carrier, reached)]
            ex = statistics.median(p[1] for p in rest) - xb
            ny = statistics.median(p[2] for p in rest) - yb
            ux, uy = math.cos(heading), math.sin(heading)
            left = -ex * uy + ny * ux
            row["beyond"] = ex * ux + ny * uy
            row["outside"] = -left if turn >= 0 else left  # a left turn's outside is to the right
        row["moved"] = len({r["vehicle"] for r in recs if r["kind"] == "rover_state"
                            and r.get("vehicle") in rovers and "over the carrier" in r.get("text", "")})
        row["touchdowns"] = [off for rid in rovers if (off := touchdown(run, rid, carrier)) is not None]
        rows.append(row)
    return rows


def touchdown(run: Run, rid: str, carrier: Track) -> float | None:
    """How far from the carrier ``rid`` first touched the ground after its last ``land`` command."""
    lands = [r["t"] for r in run.records if r["kind"] == "command" and r.get("vehicle") == rid
             and r.get("command") == "land"]
    track = run.tracks.get(run.sysid.get(rid, -1), [])
    if not lands or not track or not carrier:
        return None
    down = next((p for p in track if p[0] > lands[-1] and p[3] < GROUND), None)
    if down is None:
        return None
    c = at(carrier, down[0])
    return math.hypot(down[1] - c[1], down[2] - c[2])


def fmt(v: float | None, spec: str = ".2f") -> str:
    return "-" if v is None else format(v, spec)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folders", nargs="+", type=Path, help="folders holding kept run folders")
    args = ap.parse_args()
    rows = []
    for name, folder in collection_runs(args.folders):
        run = read_run(name, folder)
        if run is not None:
            rows += stop_rows(run)
    if not rows:
        print("no collection run with a journal, a plan and a tlog under "
              + ", ".join(map(str, args.folders)), file=sys.stderr)
        return 1
    print("| run | stop | turn into it deg | leg m | rest beyond m | rest outside m | rovers moved over "
          "| touch-downs m from the carrier | flown vs planned |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in sorted(rows, key=lambda r: abs(r["turn"])):
        downs = ", ".join(f"{d:.2f}" for d in r["touchdowns"]) or "-"
        print(f"| {r['run']} | {r['stop']} | {r['turn']:+.0f} | {r['leg']:.1f} | {fmt(r.get('beyond'))} "
              f"| {fmt(r.get('outside'))} | {r['moved']} | {downs} | {fmt(r['flown_pct'], '+.1f')} % |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
