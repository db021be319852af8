"""The carrier's legs as flown against planned, from kept firmware runs (``bench/firmware.py --runs
DIR``, ``bench/firmware_deck.py --runs DIR``, ``bench/firmware_px4.py --runs DIR``).

For every deploy and collect run found under the given folders (a run folder holds
``journal.jsonl`` and ``plan.json``) and every carrier leg of its plan, one row: the leg's length,
the heading change into it (from the heading the carrier stood at, or its previous leg), its
planned duration (the plan's arrival at the stop less its departure from the one before) and its
flown duration (mission seconds from the command that sent the carrier off - the route's start,
``set_current`` or ``start_mission`` after a stop - to ``stop_reached``), and how late it was.

Then a least-squares fit of the lateness on the heading change (seconds per radian: what the plan
should charge a radian of turn *beyond* what it charged), alone and with the leg's length beside
it (seconds per metre: a carrier that drives slower or faster than its speed limit). Zero-length
legs (a stop on the carrier's start) are left out.

Run: ``python bench/firmware_legs.py DIR [DIR ...]`` (prints markdown; ``--rows`` adds the legs).
"""

from __future__ import annotations

import argparse
import bisect
import json
import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

DEPARTURES = ("set_current", "start_mission")  # carrier commands that send it off a stop


@dataclass(frozen=True)
class Leg:
    run: str
    kind: str
    stop: int
    length: float  # m
    turn: float  # rad, 0 ... pi
    planned: float  # mission s
    flown: float  # mission s

    @property
    def late(self) -> float:
        return self.flown - self.planned


def mission_clock(rows: list[dict[str, Any]]) -> Any:
    """Mission time (the journal's ``T``) at a wall time, interpolated between the records that
    carry both."""
    pts = sorted((r["t"], r["T"]) for r in rows if "T" in r)
    ts = [t for t, _ in pts]

    def at(t: float) -> float:
        i = min(max(bisect.bisect_left(ts, t), 1), len(pts) - 1)
        (t1, m1), (t2, m2) = pts[i - 1], pts[i]
        return m1 if t2 == t1 else m1 + (m2 - m1) * (t - t1) / (t2 - t1)
    return at


def heading(a: list[float], b: list[float]) -> float:
    return math.atan2(b[1] - a[1], b[0] - a[0])


def legs_of(folder: Path, name: str) -> list[Leg]:
    rows = [json.loads(line) for line in (folder / "journal.jsonl").open()]
    plan = json.loads((folder / "plan.json").read_text())
    start_kind = "collection_started" if plan["kind"] == "collect" else "carrier_started"
    starts = [r for r in rows if r["kind"] == start_kind]
    if not starts or not any("T" in r for r in rows):
        return []
    clock = mission_clock(rows)
    reached = {r["stop"]: r["T"] for r in rows if r["kind"] == "stop_reached" and "T" in r}
    offs = [clock(r["t"]) for r in rows if r["kind"] == "command" and r.get("vehicle") == "carrier"
            and r.get("command") in DEPARTURES and "stop" in r]
    out: list[Leg] = []
    facing, left_plan, left_flown = plan["carrier"]["heading"], 0.0, starts[0].get("T", clock(starts[0]["t"]))
    for k, stop in enumerate(plan["stops"], 1):
        path = stop["carrier_path"]
        length = sum(math.dist(p[:2], q[:2]) for p, q in zip(path, path[1:], strict=False))
        if length > 0.5 and k in reached:
            turn = abs((heading(path[0], path[1]) - facing + math.pi) % math.tau - math.pi)
            out.append(Leg(name, plan["kind"], k, length, turn,
                           stop["arrive"] - left_plan, reached[k] - left_flown))
        if length > 0.5:
            facing = heading(path[-2], path[-1])
        left_plan = stop["depart"]
        if len(offs) >= k:
            left_flown = offs[k - 1]
    return out


def fit(legs: list[Leg], with_length: bool) -> tuple[list[float], float, float]:
    """Least squares of lateness on the turn (and length): coefficients, rms and worst residual."""
    cols = [[leg.turn for leg in legs]] + ([[leg.length for leg in legs]] if with_length else [])
    x = np.array(cols).T
    y = np.array([leg.late for leg in legs])
    coef, *_ = np.linalg.lstsq(x, y, rcond=None)
    res = y - x @ coef
    return [float(c) for c in coef], float(np.sqrt((res**2).mean())), float(abs(res).max())


def rms(values: list[float]) -> float:
    return math.sqrt(sum(v * v for v in values) / len(values))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folders", nargs="+", type=Path)
    ap.add_argument("--rows", action="store_true", help="print every leg")
    args = ap.parse_args()
    legs = [leg for top in args.folders for j in sorted(top.rglob("journal.jsonl"))
            if (j.parent / "plan.json").exists() for leg in legs_of(j.parent, str(j.parent.relative_to(top)))]
    if not legs:
        print("no deploy or collect runs with a carrier leg found", file=sys.stderr)
        return 1
    if args.rows:
        print("| run | command | stop | length m | turn deg | planned s | flown s | late s |")
        print("|---|---|---|---|---|---|---|---|")
        for g in sorted(legs, key=lambda g: g.turn):
            print(f"| {g.run} | {g.kind} | {g.stop} | {g.length:.1f} | {math.degrees(g.turn):.0f} | "
                  f"{g.planned:.2f} | {g.flown:.2f} | {g.late:+.2f} |")
        print()
    lates = [g.late for g in legs]
    lengths, turns = [g.length for g in legs], [math.degrees(g.turn) for g in legs]
    print(f"{len(legs)} legs of {min(lengths):.1f} - {max(lengths):.1f} m, "
          f"turning {min(turns):.0f} - {max(turns):.0f} deg\n")
    print("| model of the lateness | s per rad | s per m | rms s | worst s |")
    print("|---|---|---|---|---|")
    print(f"| as planned | - | - | {rms(lates):.2f} | {max(map(abs, lates)):.2f} |")
    (per_rad,), r1, w1 = fit(legs, False)
    print(f"| turn | {per_rad:+.2f} | - | {r1:.2f} | {w1:.2f} |")
    (per_rad, per_m), r2, w2 = fit(legs, True)
    print(f"| turn + length | {per_rad:+.2f} | {per_m:+.3f} | {r2:.2f} | {w2:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
