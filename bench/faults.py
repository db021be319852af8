"""Faults in a collection: how soon (in mission time) the controller lets a rover go that cannot
arrive, at several speed-ups, and what the collection then does.

One collection (the carrier at the origin, three rovers on the ground at r1 (12, 4), r2 (110, -6),
r3 (60, 30); ``rovers.endurance_range`` 200 m at 5 m/s) is flown by
``fleetctl.run.flight.execute`` against the in-process simulated fleet (real UDP) with one fault
on r2, which strikes on its way to its stop:

* ``battery empty`` - the mission's ``sim.faults`` ``battery_drain`` (factor 15 for r2): its
  battery empties in the air, the simulated autopilot switches to LAND (evidence: the battery
  reaching 0 in the simulation);
* ``failsafe RTL`` / ``failsafe LAND`` - its simulated autopilot switched to RTL / LAND 1 s (mission)
  after its lift-off (evidence: the switch);
* ``link lost`` - ``dropout`` of r2 from 1 s after its lift-off (evidence: the dropout; its loss is
  seen after ``links.heartbeat_timeout`` of mission time and at least one wall second, the floor
  of fleetctl.mavlink.silence, so faster than real time this row scales with the speed-up past it).

Detection = the mission time of the controller's ``rover_let_go`` (or, for the link, the rover's
``link_lost`` event) less the mission time of the evidence, both on the simulation's clock.

    python bench/faults.py [--speedup 1,20] [--only battery,rtl,land,link] [--json OUT]

Prints a markdown table.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import logging
import sys
import tempfile
from pathlib import Path
from typing import Any

import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fleetctl.mission import load_mission  # noqa: E402
from fleetctl.run.flight import execute  # noqa: E402
from sitl.flavour import Mode  # noqa: E402
from sitl.fleet import SimFleet  # noqa: E402
from sitl.world import Phase  # noqa: E402

ORIGIN = {"lat": 47.397742, "lon": 8.545594, "alt": 488.0}
VICTIM = "r2"
ROVERS = [{"id": "r1", "position": [12, 4, 0], "range": 150.0},
          {"id": "r2", "position": [110, -6, 0], "range": 150.0},
          {"id": "r3", "position": [60, 30, 0], "range": 150.0}]
FAULTS = {"battery": "battery empty", "rtl": "failsafe RTL", "land": "failsafe LAND", "link": "link lost"}
STRIKE_AFTER = 1.0  # mission s after the victim's lift-off (rtl, land, link)
DECISIONS = ("plan", "replan", "rover_let_go", "rover_loaded", "stop_reached", "carrier_released",
             "rover_unreachable", "rover_failed", "link_lost")


def mission_dict(fault: str, speedup: float) -> dict[str, Any]:
    faults = [{"kind": "battery_drain", "vehicle": VICTIM, "factor": 15.0}] if fault == "battery" else []
    return {
        "name": f"faults-{fault}",
        "origin": ORIGIN,
        "carrier": {"id": "carrier", "connection": "sim", "sysid": 1, "position": [0, 0], "heading_deg": 0,
                    "max_speed": 10.0, "accel": 5.0, "unload_time": 1.0, "load_time": 1.0},
        "rovers": {"max_speed": 5.0, "deploy_range": 40.0, "endurance_range": 200.0, "reserve": 0.1,
                   "fleet": {"count": len(ROVERS), "sysid_start": 11}},
        "tasks": [],
        "collection": {"rovers": ROVERS},
        "sim": {"speedup": speedup, "faults": faults},
        "links": {"heartbeat_timeout": 3.0},
    }


class Watcher:
    """Polls the simulation: when the evidence happened (sim time); strikes the mode and link faults."""

    def __init__(self, fault: str) -> None:
        self.fault = fault
        self.sim: SimFleet | None = None
        self.task: asyncio.Task[None] | None = None
        self.lift_off: float | None = None
        self.evidence: float | None = None
        # the poll before the evidence was seen (sim time): the evidence lies after it - a busy event
        # loop may poll tenths of a simulated second apart at speed-up 20
        self.before: float | None = None

    def attach(self, sim: SimFleet) -> None:
        self.sim = sim
        self.task = asyncio.ensure_future(self._poll())

    async def _poll(self) -> None:
        sim = self.sim
        assert sim is not None
        r = sim.rover(VICTIM)
        while self.evidence is None:
            t = sim.sim_time
            if self.lift_off is None and r.phase is Phase.AIR:
                self.lift_off = t
            if self.fault == "battery" and r.battery <= 0.0:
                self.evidence = t
                break
            if self.fault == "battery":
                self.before = t
            elif self.fault != "battery" and self.lift_off is not None and t >= self.lift_off + STRIKE_AFTER:
                if self.fault == "link":
                    sim.dropout(VICTIM)
                else:
                    sim.vehicle(VICTIM).set_mode(Mode.RTL if self.fault == "rtl" else Mode.LAND)
                self.evidence = t
            await asyncio.sleep(0.002)

    def stop(self) -> None:
        if self.task is not None:
            self.task.cancel()


async def fly(fault: str, speedup: float, tmp: Path) -> dict[str, Any]:
    """Fly the scenario with ``fault`` at ``speedup``; the row of the table and the decisions."""
    path = tmp / f"{fault}-{speedup:g}.yaml"
    path.write_text(yaml.safe_dump(mission_dict(fault, speedup), sort_keys=False))
    w = Watcher(fault)
    try:
        out = await asyncio.wait_for(execute(load_mission(path), "collect", runs_dir=tmp / "runs",
                                             on_sim=w.attach), 300)
    finally:
        w.stop()
    recs = [json.loads(line) for line in (out.run_dir / "journal.jsonl").read_text().splitlines()]
    s = out.summary
    let_go = [r for r in recs if r.get("kind") == "rover_let_go"]
    kind = "link_lost" if fault == "link" else "rover_let_go"
    seen = next((r for r in recs if r.get("kind") == kind and r.get("vehicle") == VICTIM), None)
    detected = None if seen is None else _clock_of(recs, seen)
    detection = None if detected is None or w.evidence is None else detected - w.evidence
    # the battery's end lies between two polls: the detection at most this much longer
    earliest = w.before if w.fault == "battery" else w.evidence
    detection_max = None if detected is None or earliest is None else detected - earliest
    return {
        "fault": FAULTS[fault],
        "speedup": speedup,
        "detection": detection,
        "detection_max": detection_max,
        "result": s["result"],
        "loaded": s["rovers_loaded"],
        "let_go": s.get("rovers_let_go", {}),
        "lost": s["rovers_lost"],
        "flown": s["makespan_flown"],
        "victim": s["rovers_left"].get(VICTIM) or s["rovers_lost_last_position"].get(VICTIM),
        "reason": (let_go[0]["reason"] if let_go else None),
        "decisions": decisions(recs),
    }


def _clock_of(recs: list[dict[str, Any]], rec: dict[str, Any]) -> float | None:
    """The mission clock (simulation seconds) of an event, from its T+ and an event that has both
    (``collection_started`` and ``rover_let_go`` carry the mission clock as ``at``; ``T`` is T+)."""
    anchor = next((r for r in recs if "at" in r and r.get("T") is not None), None)
    if anchor is None or rec.get("T") is None:
        return None
    return float(anchor["at"]) - float(anchor["T"]) + float(rec["T"])


def decisions(recs: list[dict[str, Any]]) -> list[tuple[str, str | None, Any]]:
    """What the controller decided, in order: plans (stops and their rovers), rovers let go (why),
    rovers loaded, stops reached and carriers released; no times."""
    out: list[tuple[str, str | None, Any]] = []
    for r in recs:
        k = r.get("kind")
        if k not in DECISIONS:
            continue
        what: Any = None
        if k in ("plan", "replan"):
            plan = r.get("plan") or r.get("new") or {}
            what = [sorted(leg["rover"] for leg in st.get("rovers", [])) for st in plan.get("stops", [])]
        elif k == "rover_let_go":
            what = str(r.get("reason", "")).split(" (")[0]
        elif k in ("stop_reached", "carrier_released"):
            what = r.get("stop")
        out.append((k, r.get("vehicle"), what))
    return out


def table(rows: list[dict[str, Any]]) -> str:
    lines = ["| fault | speedup | detection (mission s) | result | loaded | let go / lost (why) "
             "| r2 at the end |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        det = "—" if r["detection"] is None else f"{r['detection']:.2f}"
        gone = "; ".join([f"{k}: {v}" for k, v in r["let_go"].items()] + [f"{k}: lost" for k in r["lost"]])
        v = r["victim"]
        at = (f"{v.get('position')}, {v.get('state')}, battery {v.get('battery_pct')} %, "
              f"airborne {v.get('airborne')}") if isinstance(v, dict) else str(v)
        lines.append(f"| {r['fault']} | {r['speedup']:g} | {det} | {r['result']} | "
                     f"{', '.join(r['loaded'])} | {gone or '—'} | {at} |")
    return "\n".join(lines)


async def main_async(speedups: list[float], faults: list[str]) -> list[dict[str, Any]]:
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for f in faults:
            for sp in speedups:
                rows.append(await fly(f, sp, Path(d)))
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--speedup", default="1,20")
    ap.add_argument("--only", default=",".join(FAULTS))
    ap.add_argument("--json")
    a = ap.parse_args()
    logging.basicConfig(level=logging.ERROR)
    rows = asyncio.run(main_async([float(x) for x in a.speedup.split(",")], a.only.split(",")))
    print(table(rows))
    if a.json:
        Path(a.json).write_text(json.dumps(rows, indent=1, default=str))


if __name__ == "__main__":
    main()
