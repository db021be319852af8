"""The whole suite plans quick plans unless a test names a budget: ``fleetctl plan`` and a
deployment's first plan would otherwise search for up to ``fleetctl.run.budget.DEFAULT_BUDGET_MS``
(set here before any test starts, so that the CLI and the simulated fleets' subprocesses inherit
it)."""

from __future__ import annotations

import os

from fleetctl.run.budget import BUDGET_ENV

os.environ.setdefault(BUDGET_ENV, "0")
