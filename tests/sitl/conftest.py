"""Fixtures for the sitl tests: a running fleet and a ground station talking to it."""

from __future__ import annotations

from collections.abc import AsyncIterator

import pytest
from sitl_helpers import Gcs, make_config, open_gcs

from sitl import SimFleet


@pytest.fixture
async def fleet() -> AsyncIterator[SimFleet]:
    async with SimFleet(make_config()) as f:
        yield f
    assert f.errors == 0, f.last_error


@pytest.fixture
async def gcs(fleet: SimFleet) -> AsyncIterator[Gcs]:
    g = await open_gcs(fleet.endpoints["carrier"])
    await g.recv("GLOBAL_POSITION_INT", sysid=1)
    yield g
    g.close()
