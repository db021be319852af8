"""Flying a long operation (docs/operations.md, "Flying an operation"): the carrier walks the
plan's stops, picking up returning rovers, swapping their batteries and launching fresh sorties.

One module per concept: :mod:`.board` (where every sortie, task and swap stands), :mod:`.sortie`
(one rover's sortie in the air: its work, timed by the firmware, and its way back), :mod:`.swaps`
(the deck's swap station), :mod:`.changes` (tasks added or removed while flying), :mod:`.live`
(the live state a replan starts from), :mod:`.phase` (the walk over the stops, and the replans)."""

from fleetctl.run.operation.phase import OperationPhase

__all__ = ["OperationPhase"]
