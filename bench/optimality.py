"""Optimality gap of the planners against the exact reference (``planners.core.exact``) on tiny instances.

For n = 2..5 tasks (rovers) and a few seeded random instances each, the gap of ``lee`` is
(T_lee − T_ref) / T_ref, T_ref the best of every ordered partition placed by constrained
optimisation (lee's own plan is one more start, so the reference is never worse than it).
Instances are drawn so that grouping matters: tasks in a square a few deploy ranges wide.

With ``--cache FILE`` (JSON) the reference without the planner's start is computed once per
instance and kept (keyed by the instance's fingerprint); each run then takes the better of it and
the planner's own partition placed by the reference's optimiser, so quick, budgeted and
before/after runs share one reference and only pay for the planners.

Run: ``python bench/optimality.py [--seeds 8] [--sizes 2,3,4,5] [--budget-ms 200] [--cache refs.json]``;
prints markdown.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import math
import random
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from planners.collect.lee import plan_collect_lee  # noqa: E402
from planners.core.exact import exact_plan, place_partition  # noqa: E402
from planners.core.plan import Plan  # noqa: E402
from planners.core.problem import CarrierSpec, CollectProblem, CollectRover, DeployProblem, Motion, Task  # noqa: E402
from planners.deploy.lee import plan_lee  # noqa: E402


def deploy_instance(n: int, seed: int) -> DeployProblem:
    rng = random.Random(1000 * n + seed)
    d = rng.uniform(8.0, 25.0)
    size = rng.uniform(1.5, 4.0) * d
    carrier = CarrierSpec(max_speed=rng.uniform(5.0, 15.0), accel=rng.choice([None, rng.uniform(1.0, 5.0)]),
                          turn_rate=rng.choice([None, rng.uniform(0.5, 3.0)]),
                          unload_time=rng.uniform(0.0, 4.0))
    rover = Motion(rng.uniform(1.0, 4.0), rng.choice([None, rng.uniform(0.5, 3.0)]))
    tasks = tuple(Task(f"t{i}", (rng.uniform(0, size), rng.uniform(0, size), rng.uniform(0, min(d / 2, 8.0))))
                  for i in range(n))
    start = (rng.uniform(-size / 2, 0), rng.uniform(-size / 2, 0), 0.0)
    return DeployProblem(carrier, rover, d, start, rng.uniform(-math.pi, math.pi), tasks)


def collect_instance(n: int, seed: int) -> CollectProblem:
    rng = random.Random(2000 * n + seed)
    mean = rng.uniform(8.0, 25.0)
    size = rng.uniform(1.5, 4.0) * mean
    carrier = CarrierSpec(max_speed=rng.uniform(5.0, 15.0), accel=rng.choice([None, rng.uniform(1.0, 5.0)]),
                          turn_rate=rng.choice([None, rng.uniform(0.5, 3.0)]),
                          load_time=rng.uniform(0.0, 4.0))
    rover = Motion(rng.uniform(1.0, 4.0), rng.choice([None, rng.uniform(0.5, 3.0)]))
    rovers = []
    for i in range(n):
        z = rng.uniform(0, 5.0)
        rovers.append(CollectRover(f"r{i + 1}", (rng.uniform(0, size), rng.uniform(0, size), z),
                                   z + rng.uniform(0.5, 1.5) * mean))
    start = (rng.uniform(-size / 2, size), rng.uniform(-size / 2, 0), 0.0)
    return CollectProblem(carrier, rover, start, rng.uniform(-math.pi, math.pi), tuple(rovers))


Hint = tuple[list[list[int]], list[tuple[float, float]]]


def _hint(plan: Plan, ids: list[str]) -> Hint:
    index = {x: i for i, x in enumerate(ids)}
    key = "task" if plan.kind == "deploy" else "rover"
    clusters = [[index[getattr(leg, key)] for leg in s.rovers] for s in plan.stops]
    return clusters, [(s.position[0], s.position[1]) for s in plan.stops]


def reference(p: DeployProblem | CollectProblem, seed: int, hint: Hint,
              cache: dict[str, float] | None) -> float:
    """The exact reference's makespan, never worse than the planner's partition (``hint``)."""
    if cache is None:
        return exact_plan(p, seed=seed, hint=hint).makespan
    key = hashlib.sha1(repr((dataclasses.replace(p, budget_ms=None), seed)).encode()).hexdigest()
    if key not in cache:
        cache[key] = exact_plan(p, seed=seed).makespan
    return min(cache[key], place_partition(p, *hint))


def gaps(kind: str, n: int, seeds: int, budget_ms: float | None,
         cache: dict[str, float] | None = None, save: Callable[[], None] | None = None
         ) -> tuple[list[float], float]:
    out, ms = [], []
    for seed in range(seeds):
        if kind == "deploy":
            p = deploy_instance(n, seed)
            if budget_ms is not None:
                p = dataclasses.replace(p, budget_ms=budget_ms)
            plan = plan_lee(p)
            ids = [t.id for t in p.tasks]
        else:
            p = collect_instance(n, seed)
            if budget_ms is not None:
                p = dataclasses.replace(p, budget_ms=budget_ms)
            plan = plan_collect_lee(p)
            ids = [r.id for r in p.rovers]
        ref = reference(p, seed, _hint(plan, ids), cache)
        if save is not None:
            save()
        out.append(max(plan.makespan - ref, 0.0) / ref * 100 if ref > 0 else 0.0)
        ms.append(plan.compute_ms)
    return out, statistics.median(ms)


def main(argv: list[str] | None = None) -> str:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--sizes", default="2,3,4,5")
    ap.add_argument("--budget-ms", type=float, default=None)
    ap.add_argument("--kinds", default="deploy,collect")
    ap.add_argument("--cache", type=Path, default=None, help="JSON file keeping the references between runs")
    args = ap.parse_args(argv)
    cache: dict[str, float] | None = None
    if args.cache is not None:
        cache = json.loads(args.cache.read_text()) if args.cache.exists() else {}

    def save() -> None:
        if args.cache is not None:
            args.cache.write_text(json.dumps(cache, indent=0))
    sizes = [int(s) for s in args.sizes.split(",")]
    label = "quick" if args.budget_ms is None else f"budget {args.budget_ms:g} ms"
    lines = [f"| kind | n | instances | lee ({label}) mean gap % | max gap % | ≥ 0.5 % | median compute ms |",
             "|---|---|---|---|---|---|---|"]
    t0 = time.perf_counter()
    for kind in args.kinds.split(","):
        for n in sizes:
            g, ms = gaps(kind, n, args.seeds, args.budget_ms, cache, save)
            lines.append(f"| {kind} | {n} | {len(g)} | {statistics.mean(g):.2f} | {max(g):.2f} | "
                         f"{sum(x >= 0.5 for x in g)} | {ms:.1f} |")
    lines.append(f"\n(reference + planners: {time.perf_counter() - t0:.0f} s)")
    text = "\n".join(lines)
    print(text)
    return text


if __name__ == "__main__":
    main()
