"""What several commands do alike: warn about a mission that loads but looks wrong."""

from __future__ import annotations

import sys

from fleetctl.mission import Mission
from fleetctl.mission.outliers import far_task_warnings


def warn_mission(mission: Mission, collect: bool) -> None:
    """Warnings about a mission that loads but looks wrong (a task far outside the others)."""
    for line in [] if collect else far_task_warnings(mission):
        print(f"fleetctl: warning: {mission.path or mission.name}: {line}", file=sys.stderr)
