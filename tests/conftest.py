"""The whole suite plans quick plans unless a test names a budget: ``fleetctl plan`` and a
deployment's first plan would otherwise search for up to ``fleetctl.run.budget.DEFAULT_BUDGET_MS``
(set here before any test starts, so that the CLI and the simulated fleets' subprocesses inherit
it). Every test of real autopilot firmware is also ``slow`` (``scripts/test.sh -m "not slow"`` is
the quick loop; the ``slow`` marker itself is set on each slow module or test). The suite runs on
two pytest-xdist workers (scripts/test.sh); the firmware tests are one group that a single worker
flies in turn, since they bind fixed ports (PX4's ground-station port 14550, ArduPilot's instance
ports)."""

from __future__ import annotations

import os

import pytest

from fleetctl.run.budget import BUDGET_ENV

os.environ.setdefault(BUDGET_ENV, "0")


FIRMWARE_GROUP = "firmware"


def flies_firmware(item: pytest.Item) -> bool:
    return item.get_closest_marker("firmware") is not None or "ardupilot" in getattr(item, "fixturenames", ())


@pytest.hookimpl(tryfirst=True)  # before pytest-xdist names the groups
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        if flies_firmware(item):
            item.add_marker(pytest.mark.slow)
            item.add_marker(pytest.mark.xdist_group(FIRMWARE_GROUP))
