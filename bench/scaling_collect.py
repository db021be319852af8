"""Collection scaling (dissertation ch. 5.6): compute time against the number of rovers, and the
Monte Carlo makespan improvement of ``lee`` over ``visit-all``.

(a) ch. 5.6.1: rovers and carrier uniform in a 200 m square, ranges uniform in 5–20 m, carrier and
    rover parameters normal around the chapter's means (v_c 15 m/s, w_c 3 rad/s, a_c 5 m/s²,
    t_l 3 s, v_r 3 m/s; σ = 10 % of the mean); median compute time of a few seeds.
(b) ch. 5.6.2: a 300 m square, d_collect^M ∈ {10, 20, 30, 40} m with σ = 2 per rover, 10–100 rovers,
    the same parameter draws; mean improvement (visit-all − lee) / visit-all.

Run: ``python bench/scaling_collect.py`` (prints markdown). ``main()`` returns the same markdown.
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from planners import COLLECT_PLANNERS  # noqa: E402
from planners.core.problem import CarrierSpec, CollectProblem, CollectRover, Motion  # noqa: E402

SIZES = (10, 20, 50, 100, 200, 500, 1000)
CONVEX_UPTO = 200  # lee-convex beyond this takes more than ~10 s per run
SEEDS = 3


def _params(rng: np.random.Generator) -> tuple[CarrierSpec, Motion]:
    def around(mean: float) -> float:
        return float(max(rng.normal(mean, 0.1 * mean), 0.2 * mean))

    carrier = CarrierSpec(max_speed=around(15.0), accel=around(5.0), turn_rate=around(3.0),
                          load_time=around(3.0))
    return carrier, Motion(around(3.0))


def random_problem(n: int, seed: int, size: float, ranges: tuple[float, float] | None = None,
                   mean_range: float | None = None) -> CollectProblem:
    rng = np.random.default_rng(seed)
    carrier, rover = _params(rng)
    xy = rng.uniform(0, size, (n, 2))
    if ranges is not None:
        rr = rng.uniform(*ranges, n)
    else:
        rr = np.maximum(rng.normal(mean_range, 2.0, n), 1.0)
    rovers = tuple(CollectRover(f"r{i + 1}", (float(x), float(y), 0.0), float(r))
                   for i, ((x, y), r) in enumerate(zip(xy, rr, strict=True)))
    start = rng.uniform(0, size, 2)
    return CollectProblem(carrier, rover, (float(start[0]), float(start[1]), 0.0),
                          float(rng.uniform(-np.pi, np.pi)), rovers)


def compute_times() -> str:
    out = ["### Compute time (ch. 5.6.1: 200 m square, ranges 5–20 m)", "",
           f"Median CPU ms over {SEEDS} seeds; the dissertation's Matlab: over 1 s beyond 90 rovers, "
           "its convex variant 193.6 s at 100.", "",
           "| rovers | lee ms | lee-convex ms | lee stops | lee makespan s | lee-convex makespan s |",
           "|---|---|---|---|---|---|"]
    for n in SIZES:
        lee_ms, cvx_ms, stops, m_lee, m_cvx = [], [], [], [], []
        for seed in range(SEEDS):
            problem = random_problem(n, 1000 * n + seed, 200.0, ranges=(5.0, 20.0))
            t0 = time.process_time()
            plan = COLLECT_PLANNERS["lee"](problem)
            lee_ms.append((time.process_time() - t0) * 1e3)
            stops.append(len(plan.stops))
            m_lee.append(plan.makespan)
            if n <= CONVEX_UPTO:
                t0 = time.process_time()
                cvx = COLLECT_PLANNERS["lee-convex"](problem)
                cvx_ms.append((time.process_time() - t0) * 1e3)
                m_cvx.append(cvx.makespan)
        cvx_cell = f"{statistics.median(cvx_ms):.0f}" if cvx_ms else f"not run (> {CONVEX_UPTO} rovers)"
        cvx_m = f"{statistics.mean(m_cvx):.1f}" if m_cvx else "-"
        out.append(f"| {n} | {statistics.median(lee_ms):.1f} | {cvx_cell} | {statistics.mean(stops):.0f} "
                   f"| {statistics.mean(m_lee):.1f} | {cvx_m} |")
    return "\n".join(out) + "\n"


def improvement() -> str:
    sizes = (10, 20, 30, 40, 50, 60, 70, 80, 90, 100)
    ranges = (10.0, 20.0, 30.0, 40.0)
    reps = 4
    out = ["### Makespan improvement of lee over visit-all (ch. 5.6.2: 300 m square)", "",
           f"Mean of (visit-all − lee) / visit-all over {reps} random instances per cell; the dissertation's "
           "mean over its grid: 26.75 %.", "",
           "| rovers | " + " | ".join(f"d={d:g} m" for d in ranges) + " | row mean |",
           "|---|" + "---|" * (len(ranges) + 1)]
    everything = []
    for n in sizes:
        row = []
        for d in ranges:
            vals = []
            for rep in range(reps):
                problem = random_problem(n, 7919 * n + 31 * int(d) + rep, 300.0, mean_range=d)
                lee = COLLECT_PLANNERS["lee"](problem).makespan
                visit = COLLECT_PLANNERS["visit-all"](problem).makespan
                vals.append(100.0 * (visit - lee) / visit)
            row.append(statistics.mean(vals))
            everything += vals
        out.append(f"| {n} | " + " | ".join(f"{v:.1f} %" for v in row) + f" | {statistics.mean(row):.1f} % |")
    out += ["", f"**Mean improvement: {statistics.mean(everything):.2f} %** "
            f"(min {min(everything):.1f} %, max {max(everything):.1f} %, {len(everything)} instances)."]
    return "\n".join(out) + "\n"


def main() -> str:
    return "## Collection scaling (dissertation ch. 5.6)\n\n" + compute_times() + "\n" + improvement()


if __name__ == "__main__":
    print(main())
