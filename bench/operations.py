"""Long operations: the operation planner against the waves baseline and the lower bound.

Random instances: n rovers and 2–4 × n tasks in a 600 m square (heights 0–12 m), 30–300 s of work
per task, hovering (``--work ground``: landed), the carrier starting at a corner (10 m/s, 2 m/s²,
1 rad/s, 4 s unloading and loading), rovers at 5 m/s and 3 m/s² with 1.1 s take-off and 3.1 s
touch-down, 150 m launch flights, a 600 s battery with a 10 % reserve, 30 s per battery swap. Per
(rovers, tasks) row, means over the instances:

* waves: ``plan_waves`` (deploy with ``lee``, wait for the wave's work, collect with ``lee``, swap, repeat);
* planner: ``plan_operation``; gain: mean of 1 − planner / waves on the same instance;
* bound: ``operation_lower_bound``; gap: mean of (planner − bound) / planner;
* CPU ms: mean and largest process time of ``plan_operation``;
* valid: plans (planner and waves) the independent checker (tests/operation_checker.py) accepts.

Run: python bench/operations.py [--reps N] [--rovers 5,10,20] [--work hover|ground]   (prints markdown)
"""

from __future__ import annotations

import argparse
import random
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from planners.core.problem import CarrierSpec, Motion  # noqa: E402
from planners.operations import (  # noqa: E402
    OperationProblem,
    OpTask,
    operation_lower_bound,
    plan_operation,
    plan_waves,
)
from tests.operation_checker import OpSpec, check_operation  # noqa: E402

SIDE = 600.0
CARRIER = CarrierSpec(10.0, 2.0, 1.0, 4.0, 4.0, 1.1, 3.1)
ROVER = Motion(5.0, 3.0)
DEPLOY, ENDURANCE, RESERVE, SWAP, H_T, H_A = 150.0, 600.0, 0.1, 30.0, 1.0, 3.0


def random_operation(seed: int, rovers: int, tasks: int, ground: bool) -> OperationProblem:
    rng = random.Random(seed)
    ts = tuple(OpTask(f"t{i + 1}", (rng.uniform(0, SIDE), rng.uniform(0, SIDE), rng.uniform(0, 12)),
                      rng.uniform(30, 300), ground) for i in range(tasks))
    ids = tuple(f"r{i + 1}" for i in range(rovers))
    return OperationProblem(CARRIER, ROVER, (0.0, 0.0, 0.0), 0.7854, ts, ids,
                            deploy_range=DEPLOY, endurance=ENDURANCE, reserve=RESERVE, swap_time=SWAP,
                            takeoff_height=H_T, approach_height=H_A)


def spec(p: OperationProblem) -> OpSpec:
    c = p.carrier
    return OpSpec(c.max_speed, c.accel, c.turn_rate, c.unload_time, c.load_time, c.takeoff_time, c.land_time,
                  p.rover.max_speed, p.rover.accel, p.deploy_range, p.endurance, p.reserve, p.swap_time,
                  p.takeoff_height, p.approach_height,
                  {t.id: (t.position, t.duration, t.ground) for t in p.tasks},
                  p.rovers)


def _valid(plan: dict[str, object], s: OpSpec) -> bool:
    try:
        check_operation(plan, s)  # type: ignore[arg-type]
    except AssertionError:
        return False
    return True


def row(rovers: int, tasks: int, reps: int, ground: bool) -> str:
    waves, ours, bound, gain, gap, cpu, valid = [], [], [], [], [], [], 0
    for seed in range(reps):
        p = random_operation(1000 * rovers + 10 * tasks + seed, rovers, tasks, ground)
        t0 = time.process_time()
        plan = plan_operation(p)
        cpu.append((time.process_time() - t0) * 1e3)
        base = plan_waves(p)
        lb = operation_lower_bound(p)
        s = spec(p)
        valid += _valid(plan.to_json(), s) + _valid(base.to_json(), s)
        waves.append(base.makespan)
        ours.append(plan.makespan)
        bound.append(lb)
        gain.append(1.0 - plan.makespan / base.makespan)
        gap.append((plan.makespan - lb) / plan.makespan)
    m = statistics.fmean
    return (f"| {rovers} | {tasks} | {reps} | {m(waves):.0f} | {m(ours):.0f} | {100 * m(gain):.1f} % | "
            f"{m(bound):.0f} | {100 * m(gap):.1f} % | {m(cpu):.0f} / {max(cpu):.0f} | {valid}/{2 * reps} |")


def main(reps: int, fleet: list[int], ground: bool) -> str:
    lines = [f"work: {'landed' if ground else 'hovering'}", "",
             "| rovers | tasks | instances | waves s | planner s | gain vs waves | bound s | gap to bound "
             "| CPU ms mean / max | valid |", "|---|---|---|---|---|---|---|---|---|---|"]
    for n in fleet:
        for ratio in (2, 3, 4):
            lines.append(row(n, ratio * n, reps, ground))
            print(lines[-1], file=sys.stderr, flush=True)  # progress
    return "\n".join(lines)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--reps", type=int, default=5, help="instances per row")
    ap.add_argument("--rovers", default="5,10,20", help="fleet sizes (comma-separated)")
    ap.add_argument("--work", choices=("hover", "ground"), default="hover")
    args = ap.parse_args()
    print(main(args.reps, [int(x) for x in args.rovers.split(",")], args.work == "ground"))
