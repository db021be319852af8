"""Every test of real autopilot firmware is also ``slow`` (``scripts/test.sh -m "not slow"`` is
the quick loop; the ``slow`` marker itself is set on each slow module or test)."""

from __future__ import annotations

import pytest


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        if item.get_closest_marker("firmware") is not None:
            item.add_marker(pytest.mark.slow)
