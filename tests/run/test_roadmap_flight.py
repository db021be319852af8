"""The office mission (ch. 6.5.3) flown through the simulated fleet: deploy, dwell, collect, with
every vehicle's flown ground track outside the walls.

The collection problem built from live telemetry (fleetctl/run/collect.py, CollectProblem(...))
carries the mission's obstacles (``**mission.environment()``); this test also hands them to the
``lee-graph`` collection planner itself (written when the run did not).
"""

from __future__ import annotations

import asyncio
import dataclasses
from pathlib import Path

import pytest
from shapely.geometry import LineString, Point, Polygon

import planners
from fleetctl.mission import load_mission
from fleetctl.run.flight import execute
from fleetctl.run.sim import sim_mission_dict
from sitl import FleetConfig, SimFleet

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[2]
OFFICE = ROOT / "missions" / "paper" / "roadmap_office.yaml"
TOLERANCE = 0.05  # m: walls are 0.2 m thick; the track between two samples is taken as straight
SPEEDUP = 10.0  # with 2 ms sampling the carrier moves at most ~0.2 m between samples


async def test_office_run_stays_outside_the_walls(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    mission = load_mission(OFFICE)
    env = mission.environment()
    graph_collect = planners.COLLECT_PLANNERS["lee-graph"]
    monkeypatch.setitem(planners.COLLECT_PLANNERS, "lee-graph",
                        lambda problem: graph_collect(dataclasses.replace(problem, **env)))
    walls = [Polygon(p).buffer(-TOLERANCE) for p in mission.obstacles]
    walls = [w for w in walls if not w.is_empty]
    cfg = FleetConfig.from_mission_dict(sim_mission_dict(mission), speedup=SPEEDUP)
    samples: dict[str, list[tuple[float, float, float]]] = {}
    async with SimFleet(cfg) as sim:
        ids = ["carrier", *sim.world.rovers]

        async def sample() -> None:
            while True:
                for vid in ids:
                    samples.setdefault(vid, []).append(tuple(sim.world.body(vid).position))
                await asyncio.sleep(0.002)

        sampler = asyncio.create_task(sample())
        try:
            out = await execute(mission, "run", sim=sim, dwell=1.0, planner="lee-graph,lee-graph",
                                runs_dir=tmp_path / "runs")
        finally:
            sampler.cancel()
        assert sim.errors == 0, sim.last_error
    s = out.summary
    assert out.exit_code == 0, (out.error, s)
    assert sorted(s["tasks_reached"]) == sorted(t.id for t in mission.tasks)
    assert sorted(s["rovers_loaded"]) == sorted(s["assignment"].values())
    # every vehicle's sampled track (points and the short steps between them) stays out of the walls
    for vid in ids:
        track = [(p[0], p[1]) for p in samples[vid]]
        assert len(track) > 50, vid
        for a, b in zip(track, track[1:], strict=False):
            step = LineString([a, b]) if a != b else Point(a)
            for k, wall in enumerate(walls):
                assert not step.intersects(wall), (vid, a, b, k)
    carrier = samples["carrier"]
    assert max(abs(p[0] - carrier[0][0]) + abs(p[1] - carrier[0][1]) for p in carrier) > 10.0
