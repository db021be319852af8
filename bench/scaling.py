"""Planner speed and plan quality at scale (dissertation ch. 4.6, ch. 5.6).

1. ``lee`` deployment compute time for n = 10 … 1000 random tasks in a 200 m square (ch. 4.6.1:
   d_deploy 5–20 m; v_c, w_c, a_c, t_u, v_r normal around 15 m/s, 3 rad/s, 5 m/s², 3 s, 3 m/s).
2. Mean makespan improvement of ``lee`` over ``greedy2opt`` on the Monte Carlo setup of
   ch. 4.6.2 (300 m square, n = 10 … 100, d_deploy = 10 … 40 m).
3. The collection tables of bench/scaling_collect.py when it is present.

Run: python bench/scaling.py [--reps N]   (prints markdown tables)
"""

from __future__ import annotations

import argparse
import importlib.util
import random
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from planners import DEPLOY_PLANNERS  # noqa: E402
from planners.core.problem import CarrierSpec, DeployProblem, Motion, Task  # noqa: E402


def _pos(rng: random.Random, mean: float, sd: float) -> float:
    return max(rng.gauss(mean, sd), 0.1 * mean)


def random_deploy(rng: random.Random, n: int, size: float, d: float) -> DeployProblem:
    carrier = CarrierSpec(max_speed=_pos(rng, 15.0, 1.5), accel=_pos(rng, 5.0, 0.5),
                          turn_rate=_pos(rng, 3.0, 0.3), unload_time=_pos(rng, 3.0, 0.3))
    rover = Motion(min(_pos(rng, 3.0, 0.3), carrier.max_speed))
    tasks = tuple(Task(f"t{i + 1}", (rng.uniform(0, size), rng.uniform(0, size), 0.0)) for i in range(n))
    start = (rng.uniform(0, size), rng.uniform(0, size), 0.0)
    return DeployProblem(carrier, rover, d, start, rng.uniform(-3.14159, 3.14159), tasks)


def compute_time_table(seeds: int = 7) -> str:
    rows = ["| tasks | lee median CPU ms | p90 ms | stops (median) |", "|---|---|---|---|"]
    for n in (10, 20, 50, 100, 200, 500, 1000):
        times, stops = [], []
        for s in range(seeds):
            rng = random.Random(1000 * n + s)
            problem = random_deploy(rng, n, 200.0, rng.uniform(5.0, 20.0))
            t0 = time.process_time()  # CPU time: steady even when the machine is busy
            plan = DEPLOY_PLANNERS["lee"](problem)
            times.append((time.process_time() - t0) * 1e3)
            stops.append(len(plan.stops))
        times.sort()
        rows.append(f"| {n} | {statistics.median(times):.1f} | {times[int(0.9 * (len(times) - 1))]:.1f} | "
                    f"{statistics.median(stops):.0f} |")
    return "\n".join(rows)


def improvement_table(reps: int) -> str:
    ds = (10.0, 20.0, 30.0, 40.0)
    ns = (10, 20, 40, 60, 80, 100)
    rows = ["| tasks \\ d_deploy | " + " | ".join(f"{d:.0f} m" for d in ds) + " |",
            "|---|" + "---|" * len(ds)]
    every = []
    for n in ns:
        cells = []
        for d in ds:
            gains = []
            for s in range(reps):
                rng = random.Random(hash((n, d, s)) & 0xFFFFFFFF)
                problem = random_deploy(rng, n, 300.0, d)
                lee = DEPLOY_PLANNERS["lee"](problem).makespan
                greedy = DEPLOY_PLANNERS["greedy2opt"](problem).makespan
                gains.append((greedy - lee) / greedy * 100.0)
            every += gains
            cells.append(f"{statistics.mean(gains):.1f} %")
        rows.append(f"| {n} | " + " | ".join(cells) + " |")
    rows.append(f"\nMean improvement of lee over greedy2opt: **{statistics.mean(every):.2f} %** over "
                f"{len(every)} instances (min {min(every):.1f} %, the dissertation reports 25.20 %).")
    return "\n".join(rows)


def main(reps: int = 20) -> str:
    parts = ["### lee deployment compute time (200 m square, ch. 4.6.1)", compute_time_table(),
             "", f"### lee vs greedy2opt, Monte Carlo (300 m square, ch. 4.6.2, {reps} instances per cell)",
             improvement_table(reps)]
    extra = ROOT / "bench" / "scaling_collect.py"
    if extra.exists():
        spec = importlib.util.spec_from_file_location("scaling_collect", extra)
        assert spec is not None and spec.loader is not None
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        parts += ["", mod.main()]
    return "\n".join(parts)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--reps", type=int, default=20, help="Monte Carlo instances per (n, d) cell")
    print(main(ap.parse_args().reps))
