"""Replan latency and dropout detection latency, flown against the simulated fleet over UDP.

For N = 10, 50, 100 tasks (N + 2 rovers, tasks random in a 300 m square, seed 0): a deployment
is flown; when the carrier reaches its first stop, the running mission file is edited (the last
task removed, a new one added) and, when the first rover is launched, that rover drops out.
Reported: the replan latency (task-change event detected -> first new command sent, from the
journal's ``replan`` records; the lost-rover replan too) and the dropout detection latency (fault
injected -> ``lost`` event; target heartbeat_timeout + 0.5 s). Writes a markdown table on stdout.

    python bench/replan.py [--sizes 10,50,100] [--speedup 30]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import random
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fleetctl.mission import load_mission  # noqa: E402
from fleetctl.run.flight import execute  # noqa: E402
from fleetctl.run.sim import sim_mission_dict  # noqa: E402
from fleetctl.run.state import Event, FleetState  # noqa: E402
from fleetctl.views.view import View  # noqa: E402
from sitl import FleetConfig, SimFleet  # noqa: E402

HB = 1.5


def mission(n: int, speedup: float) -> dict[str, Any]:
    rng = random.Random(0)
    tasks = [{"id": f"t{i + 1}", "position": [round(rng.uniform(0, 300), 1),
                                              round(rng.uniform(20, 300), 1), round(rng.uniform(2, 8), 1)]}
             for i in range(n)]
    return {"name": f"bench{n}", "origin": {"lat": 47.397742, "lon": 8.545594, "alt": 488.0},
            "carrier": {"id": "carrier", "connection": "sim", "sysid": 1, "position": [0, 0],
                        "heading_deg": 0, "max_speed": 10.0, "accel": 5.0, "turn_rate": None,
                        "unload_time": 1.0, "load_time": 1.0},
            "rovers": {"max_speed": 3.0, "accel": None, "deploy_range": 40.0, "endurance_range": 400.0,
                       "reserve": 0.1, "fleet": {"count": n + 2, "sysid_start": 11}},
            "tasks": tasks, "sim": {"speedup": speedup, "faults": []}, "links": {"heartbeat_timeout": HB}}


class Probe(View):
    def __init__(self, sim: SimFleet, path: Path, d: dict[str, Any]) -> None:
        self.sim, self.path, self.d = sim, path, d
        self.state: FleetState | None = None
        self.edited = False
        self.dropped: tuple[str, float] | None = None
        self.detect: float | None = None

    def start(self, state: FleetState, fleet: Any) -> None:
        if self.state is None:
            self.state = state
            state.add_listener(self.on)

    def on(self, ev: Event) -> None:
        if ev.kind == "stop_reached" and not self.edited:
            self.edited = True
            d = dict(self.d)
            d["tasks"] = self.d["tasks"][:-1] + [{"id": "tnew", "position": [150.0, 150.0, 4.0]}]
            self.path.write_text(yaml.safe_dump(d, sort_keys=False), encoding="utf-8")
        elif ev.kind == "rover_launched" and self.dropped is None and ev.vehicle:
            self.dropped = (ev.vehicle, time.monotonic())
            self.sim.dropout(ev.vehicle)
        elif (ev.kind == "link_lost" and self.dropped and ev.vehicle == self.dropped[0]
              and self.detect is None):
            self.detect = time.monotonic() - self.dropped[1]

    async def stop(self) -> None:
        pass


async def one(n: int, speedup: float) -> dict[str, Any]:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "m.yaml"
        d = mission(n, speedup)
        path.write_text(yaml.safe_dump(d, sort_keys=False), encoding="utf-8")
        m = load_mission(path)
        cfg = FleetConfig.from_mission_dict(sim_mission_dict(m), speedup=speedup)
        async with SimFleet(cfg) as sim:
            probe = Probe(sim, path, d)
            out = await asyncio.wait_for(
                execute(m, "deploy", sim=sim, runs_dir=Path(tmp) / "runs", view=probe), 900)
        recs = [json.loads(x) for x in (out.run_dir / "journal.jsonl").read_text().splitlines()]
    reps = [r for r in recs if r.get("n") is not None and "latency_ms" in r and "old_plan" in r]
    timed = [r for r in reps if r["latency_ms"] is not None]
    by = {"tasks": [r["latency_ms"] for r in timed if "tasks changed" in r["cause"]],
          "lost": [r["latency_ms"] for r in timed if "lost" in r["cause"]]}
    return {"n": n, "replans": out.summary["replans"], "task": by["tasks"], "lost": by["lost"],
            "detect": probe.detect, "result": out.summary["result"]}


def fmt(xs: list[float]) -> str:
    return "–" if not xs else f"{max(xs):.1f}"


async def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", default="10,50,100")
    ap.add_argument("--speedup", type=float, default=30.0)
    a = ap.parse_args()
    rows = [await one(int(s), a.speedup) for s in a.sizes.split(",")]
    print(f"heartbeat_timeout {HB} s (mission time, and at least min(it, 1 s) of wall time), "
          f"sim speedup {a.speedup:g}; detection in wall s\n")
    print("| tasks | replans | task change → first command (ms) | rover lost → first command (ms) "
          "| dropout detected after (s) | target detect ≤ (s) | result |")
    print("|---:|---:|---:|---:|---:|---:|---|")
    for r in rows:
        det = "–" if r["detect"] is None else f"{r['detect']:.2f}"
        print(f"| {r['n']} | {r['replans']} | {fmt(r['task'])} | {fmt(r['lost'])} | {det} | {HB + 0.5:.1f} "
              f"| {r['result']} |")


if __name__ == "__main__":
    asyncio.run(main())
