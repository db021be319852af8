"""Fixtures for the controller tests: a simulated fleet (real UDP) and the controller connected to it."""

from __future__ import annotations

from collections.abc import AsyncIterator
from pathlib import Path

import pytest

from fleetctl.mavlink.fleet import Fleet, connect_fleet
from sitl import SimFleet
from tests.run.ctl_helpers import mission_dict, mission_from, sim_fleet


@pytest.fixture
async def sim() -> AsyncIterator[SimFleet]:
    async with sim_fleet(mission_dict()) as f:
        yield f


@pytest.fixture
async def fleet(sim: SimFleet, tmp_path: Path) -> AsyncIterator[Fleet]:
    mission = mission_from(mission_dict(), tmp_path)
    async with await connect_fleet(mission, sim.endpoints, timeout=5.0) as f:
        yield f
