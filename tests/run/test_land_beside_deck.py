"""A rover that touches down beside the deck (docs/mavlink.md): it takes off and is brought down over
the carrier once more; one that lands beside it again is reported not loaded, with where it stands.
The simulated fleet's ``land_drift`` fault moves a landing sideways on its way down, as PX4 SIH's LAND
mode does (0.1 - 1.1 m from 3 m, measured)."""

from __future__ import annotations

import asyncio
import json
from pathlib import Path
from typing import Any

import pytest

from fleetctl.mission import MissionError
from fleetctl.run.flight import execute
from fleetctl.run.sim import sim_fleet_config
from sitl import SimFleet
from sitl.world import Phase
from tests.run.ctl_helpers import mission_dict, mission_from

SPEEDUP = 20.0


def collection(drift: float) -> dict[str, Any]:
    d = mission_dict(rovers=2, faults=[{"vehicle": "r1", "kind": "land_drift", "distance": drift}])
    d["collection"] = {"rovers": [{"id": "r1", "position": [20, 10, 5], "range": 300.0},
                                  {"id": "r2", "position": [35, -12, 4], "range": 250.0}]}
    return d


def journal(run_dir: Path) -> list[dict[str, Any]]:
    return [json.loads(line) for line in (run_dir / "journal.jsonl").read_text().splitlines() if line]


async def collect(d: dict[str, Any], tmp_path: Path, *, heal: bool) -> tuple[Any, SimFleet]:
    """Collect on the simulated fleet; with ``heal`` only r1's first landing drifts (the fault is
    removed once that landing has begun: its drift is set when it begins)."""
    mission = mission_from(d, tmp_path)
    async with SimFleet(sim_fleet_config(mission, "collect", speedup=SPEEDUP)) as sim:
        async def healer() -> None:
            while not sim.rover("r1").landing:
                await asyncio.sleep(0.005)
            sim.faults.remove("land_drift", "r1")

        task = asyncio.create_task(healer()) if heal else None
        try:
            run = execute(mission, "collect", sim=sim, runs_dir=tmp_path / "runs")
            out = await asyncio.wait_for(run, 120)
        finally:
            if task is not None:
                task.cancel()
    return out, sim


async def test_a_rover_that_lands_beside_the_deck_takes_off_and_lands_on_it(tmp_path: Path) -> None:
    out, sim = await collect(collection(2.5), tmp_path, heal=True)
    s = out.summary
    assert out.exit_code == 0, (out.error, s)
    assert sorted(s["rovers_loaded"]) == ["r1", "r2"] and s["result"] == "complete"
    assert sim.rover("r1").loaded and sim.rover("r2").loaded
    texts = [r.get("text", "") for r in journal(out.run_dir)
             if r["kind"] == "rover_state" and r.get("vehicle") == "r1"]
    again = [t for t in texts if "beside its deck: taking off to land again" in t]
    assert len(again) == 1 and again[0].startswith("r1: landed 2.5 m off the carrier at stop"), texts
    assert s["makespan_flown"] > s["makespan_planned"]  # the second landing is not in the plan
    # its motors are off before it is armed and told to take off (an autopilot that disarms itself
    # just after the take-off command would keep it on the ground: PX4 SIH did)
    rows = journal(out.run_dir)
    since = next(i for i, r in enumerate(rows) if "taking off to land again" in r.get("text", ""))
    after = [(r["kind"], r.get("command")) for r in rows[since:]
             if r.get("vehicle") == "r1" and r["kind"] in ("command", "disarmed")]
    assert ("command", "arm") in after and ("command", "takeoff") in after, after
    arm = after.index(("command", "arm"))
    assert arm < after.index(("command", "takeoff"))
    off = any(k == "disarmed" or c == "disarm" for k, c in after[:arm])
    assert off or _disarmed_before(rows, since), after


def _disarmed_before(rows: list[dict[str, Any]], since: int) -> bool:
    """r1 was disarmed, and not armed again, before record ``since``."""
    state = None
    for r in rows[:since]:
        if r.get("vehicle") == "r1" and r["kind"] in ("armed", "disarmed"):
            state = r["kind"]
    return state == "disarmed"


async def test_a_rover_that_lands_beside_the_deck_twice_is_reported_not_loaded(tmp_path: Path) -> None:
    out, sim = await collect(collection(2.5), tmp_path, heal=False)
    s = out.summary
    assert out.exit_code == 1 and s["result"] == "incomplete"
    assert s["rovers_loaded"] == ["r2"]
    why = "not loaded (landed 2.5 m off the carrier, beside its deck, 2 times)"
    assert s["rovers_not_loaded_reasons"]["r1"] == why, s
    assert s["rovers_left"]["r1"]["state"] == "landed" and not s["rovers_left"]["r1"]["airborne"]
    assert sim.rover("r1").phase is Phase.GROUND  # on the ground beside the carrier, not on it


def test_a_land_drift_fault_needs_its_distance(tmp_path: Path) -> None:
    d = mission_dict(rovers=1, faults=[{"vehicle": "r1", "kind": "land_drift"}])
    with pytest.raises(MissionError, match="land_drift needs 'distance"):
        mission_from(d, tmp_path)
    fault = {"vehicle": "r1", "kind": "low_battery", "level": 0.5, "distance": 1.0}
    d = mission_dict(rovers=1, faults=[fault])
    with pytest.raises(MissionError, match="'distance' does not apply to kind low_battery"):
        mission_from(d, tmp_path)


def test_docs_state_the_second_try() -> None:
    from fleetctl.run.collect import RELANDS_MAX
    from fleetctl.run.state import DECK_RADIUS

    text = (Path(__file__).resolve().parents[2] / "docs" / "mavlink.md").read_text()
    assert f"more than {DECK_RADIUS:g} m from the carrier" in text
    assert f"after {RELANDS_MAX} such second try" in text
