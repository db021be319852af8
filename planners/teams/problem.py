"""Several carriers on one mission: the problem of sharing tasks (or rovers) between teams.

A team is one carrier with the rovers on its deck. ``TeamsProblem`` holds one ordinary planning
problem per team (``DeployProblem`` or ``CollectProblem``: that team's carrier, start, heading and
deck) whose pool — the tasks to deploy to, or the rovers to collect — is the whole mission's; an
allocation hands each pool item to exactly one team, and ``restrict`` gives a team its share.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Generic, Literal, TypeVar

from planners.core.problem import CollectProblem, CollectRover, DeployProblem, PlanningError, Task, Vec3

P = TypeVar("P", DeployProblem, CollectProblem)


@dataclass(frozen=True)
class TeamsProblem(Generic[P]):
    """One problem per team (``carriers[k]`` names team k's carrier), all with the same pool."""

    carriers: tuple[str, ...]
    problems: tuple[P, ...]

    def __post_init__(self) -> None:
        if not self.problems or len(self.carriers) != len(self.problems):
            raise PlanningError(f"{len(self.carriers)} carrier ids for {len(self.problems)} team problems")
        sizes = {len(_pool(p)) for p in self.problems}
        if len(sizes) != 1:
            raise PlanningError("every team's problem must hold the same pool of tasks or rovers")

    @property
    def kind(self) -> Literal["deploy", "collect"]:
        return "deploy" if isinstance(self.problems[0], DeployProblem) else "collect"

    @property
    def n_teams(self) -> int:
        return len(self.problems)

    @property
    def n_items(self) -> int:
        """Pool size: tasks (deployment) or rovers to collect (collection)."""
        return len(_pool(self.problems[0]))

    def positions(self) -> list[Vec3]:
        """Where each pool item is: a task, or a rover waiting to be collected."""
        return [item.position for item in _pool(self.problems[0])]

    def starts(self) -> list[Vec3]:
        return [p.start for p in self.problems]

    def capacity(self, team: int) -> int:
        """How many pool items team ``team`` may take: its deck in deployment (one rover per task);
        in collection a rover may land on any carrier, so every rover."""
        p = self.problems[team]
        if isinstance(p, DeployProblem):
            return len(p.rovers) if p.rovers else len(p.tasks)
        return self.n_items

    def stop_time(self, team: int) -> float:
        """Team ``team``'s carrier's time at a stop: unload + take-off clearance (deployment), or
        touch-down + load once its rovers are there (collection)."""
        c = self.problems[team].carrier
        return c.deploy_stop_time if self.kind == "deploy" else c.collect_stop_time

    def restrict(self, team: int, members: Sequence[int]) -> P:
        """Team ``team``'s own problem: its carrier and deck with the pool items ``members``."""
        p = self.problems[team]
        if isinstance(p, DeployProblem):
            return replace(p, tasks=tuple(p.tasks[i] for i in members))
        return replace(p, rovers=tuple(p.rovers[i] for i in members))


def _pool(p: DeployProblem | CollectProblem) -> tuple[Task, ...] | tuple[CollectRover, ...]:
    return p.tasks if isinstance(p, DeployProblem) else p.rovers
