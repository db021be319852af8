"""Several carriers on the same tasks and rovers: what 1–4 teams buy.

Monte Carlo instances as in ch. 4.6.2 (bench/scaling.py): n = 20 … 100 tasks in a 300 m square,
d_deploy 10–40 m, carrier and rover parameters drawn around 15 m/s, 5 m/s², 3 rad/s, 3 s unload,
3 m/s, in the dissertation's time model (no take-off or touch-down terms, like bench/scaling.py).
Each instance draws four carrier starts (and headings) in the square; with m carriers the first m
start, all of the instance's carrier type, and the n rovers are split between their decks as
evenly as possible (the same rovers as the one carrier has). Per (n, m) row:

* makespan: mean over the instances (``planners.teams.plan_teams``, each team by ``lee``);
* vs 1 carrier: mean of makespan(m) / makespan(1) on the same instance;
* vs nearest: mean improvement over the nearest-carrier baseline (every task to the carrier
  starting nearest, each team by ``lee``); never negative by construction;
* gap to LB: mean (makespan − lower bound) / makespan (``teams_lower_bound``);
* CPU ms: median process time of the allocation (planning every team included), and the mean
  number of team plans it computed.

Run: python bench/multi_carrier.py [--reps N] [--collect]   (prints a markdown table)
With --collect the same for collection: n rovers on the ground in the square, ranges 10–40 m.
"""

from __future__ import annotations

import argparse
import random
import statistics
import sys
import time
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.scaling import random_deploy  # noqa: E402
from planners import COLLECT_PLANNERS, DEPLOY_PLANNERS, SCREEN_PLANNERS  # noqa: E402
from planners.core.problem import CollectProblem, CollectRover, DeployProblem  # noqa: E402
from planners.teams import TeamsProblem, plan_teams, plan_teams_nearest, teams_lower_bound  # noqa: E402

SIZE = 300.0
TASKS = (20, 40, 60, 80, 100)
CARRIERS = (1, 2, 3, 4)


def _decks(n: int, m: int) -> list[tuple[str, ...]]:
    sizes = [n // m + (1 if k < n % m else 0) for k in range(m)]
    out, first = [], 0
    for s in sizes:
        out.append(tuple(f"r{first + j + 1}" for j in range(s)))
        first += s
    return out


def instance(seed: int, n: int, collect: bool) -> tuple[DeployProblem | CollectProblem, list[tuple]]:
    """One carrier's problem on the instance, and the four carrier starts (x, y, heading)."""
    rng = random.Random(seed)
    base = random_deploy(rng, n, SIZE, rng.uniform(10.0, 40.0))
    starts = [(rng.uniform(0, SIZE), rng.uniform(0, SIZE), rng.uniform(-3.14159, 3.14159)) for _ in range(4)]
    if not collect:
        return base, starts
    rovers = tuple(CollectRover(f"r{i + 1}", t.position, rng.uniform(10.0, 40.0))
                   for i, t in enumerate(base.tasks))
    return CollectProblem(replace(base.carrier, load_time=base.carrier.unload_time), base.rover, base.start,
                          base.heading, rovers), starts


def teams(problem: DeployProblem | CollectProblem, starts: list[tuple], m: int) -> TeamsProblem:
    probs = []
    for k, (x, y, h) in enumerate(starts[:m]):
        p = replace(problem, start=(x, y, 0.0), heading=h)
        probs.append(replace(p, rovers=_decks(len(p.tasks), m)[k]) if isinstance(p, DeployProblem) else p)
    return TeamsProblem(tuple(f"c{k + 1}" for k in range(m)), tuple(probs))


def row(n: int, m: int, reps: int, collect: bool, one: dict[int, float], screen: bool = True) -> str:
    planner = COLLECT_PLANNERS["lee"] if collect else DEPLOY_PLANNERS["lee"]
    quick = SCREEN_PLANNERS["collect" if collect else "deploy"]["lee"] if screen else None
    spans, vs_one, vs_near, gaps, cpu, calls = [], [], [], [], [], []
    for s in range(reps):
        problem, starts = instance(1000 * n + s, n, collect)
        tp = teams(problem, starts, m)
        t0 = time.process_time()
        plan = plan_teams(tp, planner, "lee", screen=quick)
        cpu.append((time.process_time() - t0) * 1e3)
        near = plan_teams_nearest(tp, planner, "lee").makespan
        bound = teams_lower_bound(tp)
        if m == 1:
            one[s] = plan.makespan
        spans.append(plan.makespan)
        vs_one.append(plan.makespan / one[s])
        vs_near.append((near - plan.makespan) / near * 100.0)
        gaps.append((plan.makespan - bound) / plan.makespan * 100.0)
        calls.append(int(plan.notes[0].split()[0]))
    return (f"| {n} | {m} | {statistics.mean(spans):.1f} | {statistics.mean(vs_one):.2f} | "
            f"{statistics.mean(vs_near):.1f} % (max {max(vs_near):.1f} %) | {statistics.mean(gaps):.0f} % | "
            f"{statistics.median(cpu):.0f} | {statistics.mean(calls):.0f} |")


def main(reps: int, collect: bool, tasks: tuple[int, ...] = TASKS, screen: bool = True) -> str:
    what = "collection" if collect else "deployment"
    lines = [f"### {what} by 1–4 carriers, {reps} instances per row (300 m square, same tasks and rovers)",
             "",
             "| tasks | carriers | makespan s | vs 1 carrier | vs nearest | gap to LB | CPU ms (median) | "
             "team plans |", "|---|---|---|---|---|---|---|---|"]
    for n in tasks:
        one: dict[int, float] = {}
        for m in CARRIERS:
            lines.append(row(n, m, reps, collect, one, screen))
            print(lines[-1], file=sys.stderr, flush=True)  # progress
    return "\n".join(lines)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--reps", type=int, default=5, help="Monte Carlo instances per row")
    ap.add_argument("--collect", action="store_true", help="collection instead of deployment")
    ap.add_argument("--tasks", default=",".join(map(str, TASKS)), help="comma-separated task counts")
    ap.add_argument("--no-screen", action="store_true",
                    help="score candidate shares with lee itself (not its screening form, SCREEN_PLANNERS)")
    args = ap.parse_args()
    print(main(args.reps, args.collect, tuple(int(x) for x in args.tasks.split(",")), not args.no_screen))
