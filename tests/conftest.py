"""The whole suite plans quick plans unless a test names a budget: ``fleetctl plan`` and a
deployment's first plan would otherwise search for up to ``fleetctl.run.budget.DEFAULT_BUDGET_MS``
(set here before any test starts, so that the CLI and the simulated fleets' subprocesses inherit
it). Every test of real autopilot firmware is also ``slow`` (``scripts/test.sh -m "not slow"`` is
the quick loop; the ``slow`` marker itself is set on each slow module or test)."""

from __future__ import annotations

import os

import pytest

from fleetctl.run.budget import BUDGET_ENV

os.environ.setdefault(BUDGET_ENV, "0")


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        if item.get_closest_marker("firmware") is not None:
            item.add_marker(pytest.mark.slow)
