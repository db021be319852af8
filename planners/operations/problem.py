"""A long operation (docs/operations.md): more tasks than rovers, each task needing
``duration`` seconds of work; rovers fly sorties from the carrier's deck, chain tasks while their
battery allows, come back and get a fresh battery (``swap_time`` on the deck) before the next one."""

from __future__ import annotations

from dataclasses import dataclass

from planners.core.problem import CarrierSpec, Motion, Vec3


@dataclass(frozen=True)
class OpTask:
    id: str
    position: Vec3
    duration: float  # s of work at the task
    ground: bool = False  # worked landed (no battery burnt while working) instead of hovering


@dataclass(frozen=True)
class OperationProblem:
    """Every rover starts on the deck with a full battery; the operation ends when every task has
    had its work and every rover is back on the deck.

    Energy: a second in the air costs 1/``endurance`` of a battery (hovering included, landed at a
    ground task nothing); a sortie may use ``1 − reserve`` of it (:attr:`air_budget` seconds).
    A launch flight (deck to first task) is at most ``deploy_range`` metres, as in a deployment.
    """

    carrier: CarrierSpec
    rover: Motion  # flight in the air (fixed_time 0); a take-off from the ground adds takeoff_time
    start: Vec3
    heading: float
    tasks: tuple[OpTask, ...]
    rovers: tuple[str, ...]
    deploy_range: float
    endurance: float  # s in the air on a full battery
    reserve: float = 0.1  # fraction of the battery never planned away
    swap_time: float = 0.0  # s to swap one rover's battery on the deck (one swap at a time)
    takeoff_height: float = 0.0  # a launched rover's line starts this high above the stop
    approach_height: float = 0.0  # a returning rover's line ends this high above its pick-up stop
    seed: int = 0

    @property
    def air_budget(self) -> float:
        """Seconds a sortie may spend in the air (take-off to touch-down) on a full battery."""
        return (1.0 - self.reserve) * self.endurance
