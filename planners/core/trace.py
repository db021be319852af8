"""Phase tracing of the quick plans: ``lee_clusters`` and ``lee_route`` call a ``Trace`` with each
phase's name and the route's makespan after it, so a benchmark can time what every phase costs
and gains (``bench/phases.py``). Planning itself never reads it."""

from __future__ import annotations

from collections.abc import Callable

Trace = Callable[[str, float], None]


def untraced(phase: str, makespan: float) -> None:
    """The default ``Trace``: nothing."""
