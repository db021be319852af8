"""What a phase hands back to the runner: :class:`PhaseResult`."""

from __future__ import annotations

from dataclasses import dataclass, field

from planners.core.plan import Plan


@dataclass
class PhaseResult:
    kind: str  # "deploy" | "collect" | "operation"
    plan: Plan | None = None
    complete: bool = False
    planned: float | None = None  # planned makespan (mission seconds)
    flown: float | None = None  # flown makespan (mission seconds), None when not complete
    started: float | None = None  # mission clock when the carrier started
    tasks_reached: list[str] = field(default_factory=list)
    tasks_done: list[str] = field(default_factory=list)  # operation: the task's duration of work done
    tasks_unserved: list[str] = field(default_factory=list)
    rovers_loaded: list[str] = field(default_factory=list)
    rovers_lost: list[str] = field(default_factory=list)
    rovers_unreachable: list[str] = field(default_factory=list)  # collect: too little range to be picked up
    rovers_let_go: dict[str, str] = field(default_factory=dict)  # collect: cannot arrive -> why
    rovers_failed: dict[str, str] = field(default_factory=dict)  # collect: not brought in -> why
    assignment: dict[str, str] = field(default_factory=dict)  # task -> rover (deploy)
    substitutions: list[dict[str, str]] = field(default_factory=list)  # refused rover -> spare
    error: str | None = None
    unserved_reasons: dict[str, str] = field(default_factory=dict)  # deploy: task -> why not reached
    tasks_all: list[str] = field(default_factory=list)  # deploy: the live task set at the end
    tasks_added: list[str] = field(default_factory=list)
    tasks_removed: list[str] = field(default_factory=list)
    launched: list[str] = field(default_factory=list)  # deploy: rovers that left the deck
    rejoined: list[str] = field(default_factory=list)  # deploy: rovers in the field without a task
    airborne: list[str] = field(default_factory=list)  # deploy: rovers still flying to a task at the end


__all__ = ["PhaseResult"]
