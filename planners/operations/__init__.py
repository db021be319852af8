"""Long operations (docs/operations.md): more tasks than rovers, task durations,
sorties with pick-ups timed to the work, battery swaps on the deck. Pure maths, no I/O.

``plan_operation`` (the planner), ``plan_waves`` (the operator's baseline: deploy, wait, collect,
swap, repeat) and ``operation_lower_bound``.
"""

from planners.operations.live import CallBack, InFlight, LiveState, air_needed, call_back
from planners.operations.lower_bound import operation_lower_bound
from planners.operations.plan import OperationPlan
from planners.operations.planner import plan_operation
from planners.operations.problem import OperationProblem, OpTask
from planners.operations.waves import plan_waves

OPERATION_PLANNERS = {"operation": plan_operation, "waves": plan_waves}

__all__ = ["OPERATION_PLANNERS", "CallBack", "InFlight", "LiveState", "OpTask", "OperationPlan",
           "OperationProblem", "air_needed", "call_back", "operation_lower_bound", "plan_operation",
           "plan_waves"]
