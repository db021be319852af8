"""How long a plan may search: the default budget of offline plans, the cap of replans in flight.

An offline plan (``fleetctl plan``, and the first deployment plan of ``deploy`` and ``run``, made
while the rovers are still on the deck) runs the planners' anytime search (``budget_ms``), which
ends sooner when it converges. The first collection plan is made while the rovers hover in the
field, burning their batteries: it searches only for a budget the mission or the command line
names. A replan is made while the fleet waits: the quick plan, or at most ``REPLAN_BUDGET_MS`` of
search when a budget is named. No I/O beyond reading one environment variable; imported by the
CLI at start-up.
"""

from __future__ import annotations

import os

# A replan (every plan of a phase after its first) with a named budget searches until this long after
# planning began: with the step under way when it ends, a replan at 100 tasks (rovers) answers within
# 50 ms of CPU (bench/scaling.py --speed).
REPLAN_BUDGET_MS = 40.0
# An offline plan (``fleetctl plan``, a deployment's first) when neither the mission nor the command
# line names a budget: the anytime search for up to this long, ending sooner when it converges (the planners'
# patience; bench/headroom.py compares it with a 3 s and a 30 s search); replans without a named
# budget are the quick plan.
DEFAULT_BUDGET_MS = 3000.0
BUDGET_ENV = "FLEETCTL_DEFAULT_BUDGET_MS"  # overrides DEFAULT_BUDGET_MS (ms; 0: the quick plan)


def default_budget_ms() -> float | None:
    """The budget of an offline plan that names none: ``DEFAULT_BUDGET_MS``, or the environment's
    ``FLEETCTL_DEFAULT_BUDGET_MS``; None (the quick plan) for 0."""
    text = os.environ.get(BUDGET_ENV, "").strip()
    try:
        value = float(text) if text else DEFAULT_BUDGET_MS
    except ValueError:
        raise ValueError(f"{BUDGET_ENV}={text!r}: expected a number of milliseconds") from None
    return value if value > 0 else None


def offline_budget(named: float | None) -> float | None:
    """The budget of an offline plan (``plan``, a deployment's first): the one named (0: the quick
    plan, None), else ``default_budget_ms()``."""
    if named is None:
        return default_budget_ms()
    return named if named > 0 else None


def replan_budget(named: float | None) -> float | None:
    """The budget of a replan in flight: the one named, at most ``REPLAN_BUDGET_MS``; none named
    (or 0): the quick plan."""
    if named is None or named <= 0:
        return None
    return min(named, REPLAN_BUDGET_MS)


__all__ = ["BUDGET_ENV", "DEFAULT_BUDGET_MS", "REPLAN_BUDGET_MS", "default_budget_ms", "offline_budget",
           "replan_budget"]
