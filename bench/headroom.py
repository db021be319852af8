"""Headroom of the default plan against the anytime search (target: within 0.5 % mean, 2 % worst of a
3-second search; the dissertation's Table 4.3 at most 40.2 s).

The default plan is what ``fleetctl plan``, ``deploy`` and ``run`` fly when neither the mission nor
the command line names a budget: ``fleetctl.run.budget.offline_budget(None)`` (the anytime search
for up to ``DEFAULT_BUDGET_MS``, ending sooner when it converges). Per instance it prints the quick
plan (no budget), the default, a 3 s search and, with ``--long-ms``, a longer search (30 s in the
issue), each as makespan and as headroom (T − T_3s) / T_3s in per cent; then the mean and worst.

Instances: random deployment missions of 10–100 tasks (bench/scaling.py's parameter draws in a
100–300 m square, d_deploy 8–25 m) and random collection missions of 10–100 rovers
(bench/scaling_collect.py's, ranges 5–25 m), seeded; and Table 4.3 (missions/paper/
deploy_15tasks_d25.yaml under the dissertation's time model). Budgets are wall-clock: on a loaded
machine the searches get less done, so say how loaded the machine was.

Run: ``python bench/headroom.py [--sizes 10,20,40,60,80,100] [--seeds 2] [--long-ms 30000]``
(prints markdown).
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import random
import statistics
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fleetctl.mission import load_mission  # noqa: E402
from fleetctl.run.budget import offline_budget  # noqa: E402
from planners import COLLECT_PLANNERS, DEPLOY_PLANNERS  # noqa: E402
from planners.core.timing import dissertation_model  # noqa: E402

SEARCH_MS = 3000.0  # the reference: a 3-second anytime search


def _bench(name: str) -> ModuleType:
    spec = importlib.util.spec_from_file_location(name, ROOT / "bench" / f"{name}.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def instances(sizes: list[int], seeds: int) -> Iterator[tuple[str, Callable[[Any], Any], Any]]:
    """(name, planner, problem) of every instance."""
    scaling, collect = _bench("scaling"), _bench("scaling_collect")
    for n in sizes:
        for s in range(seeds):
            rng = random.Random(77 * n + s)
            yield (f"deploy {n} #{s}", DEPLOY_PLANNERS["lee"],
                   scaling.random_deploy(rng, n, rng.uniform(100, 300), rng.uniform(8.0, 25.0)))
            yield (f"collect {n} #{s}", COLLECT_PLANNERS["lee"],
                   collect.random_problem(n, 99 * n + s, rng.uniform(100, 300), ranges=(5.0, 25.0)))
    table = load_mission(ROOT / "missions" / "paper" / "deploy_15tasks_d25.yaml").deploy_problem()
    yield "Table 4.3 (deploy 15, d=25)", DEPLOY_PLANNERS["lee"], dissertation_model(table)


def _planned(planner: Callable[[Any], Any], problem: Any, budget: float | None) -> tuple[float, float]:
    """Makespan and wall seconds of ``planner`` with ``budget`` (ms; None: the quick plan)."""
    t0 = time.perf_counter()
    plan = planner(dataclasses.replace(problem, budget_ms=budget))
    return plan.makespan, time.perf_counter() - t0


def main(argv: list[str] | None = None) -> str:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="10,20,40,60,80,100", help="tasks (rovers) per instance")
    ap.add_argument("--seeds", type=int, default=2, help="instances per size and kind")
    ap.add_argument("--long-ms", type=float, default=None, help="also a search this long (e.g. 30000)")
    args = ap.parse_args(argv)
    default = offline_budget(None)
    cols = ["quick", f"default ({'quick' if default is None else f'≤ {default:.0f} ms'})", "3 s"]
    cols += [f"{args.long_ms / 1e3:g} s"] if args.long_ms else []
    lines = ["| instance | " + " | ".join(f"{c} s" for c in cols) + " | default wall s | quick vs 3 s % "
             "| default vs 3 s % |" + (" long vs 3 s % |" if args.long_ms else ""),
             "|---|" + "---|" * (len(cols) + 3 + (1 if args.long_ms else 0))]
    gaps: dict[str, list[float]] = {"quick": [], "default": [], "long": []}
    table_default = None
    for name, planner, problem in instances([int(s) for s in args.sizes.split(",")], args.seeds):
        quick, _ = _planned(planner, problem, None)
        mine, wall = _planned(planner, problem, default)
        ref, _ = _planned(planner, problem, SEARCH_MS)
        row = [quick, mine, ref]
        if args.long_ms:
            row.append(_planned(planner, problem, args.long_ms)[0])
        gap = [100 * (t - ref) / ref for t in row]
        if name.startswith("Table"):
            table_default = mine
        else:
            gaps["quick"].append(gap[0])
            gaps["default"].append(gap[1])
            if args.long_ms:
                gaps["long"].append(gap[3])
        lines.append(f"| {name} | " + " | ".join(f"{t:.2f}" for t in row) + f" | {wall:.2f} | {gap[0]:+.2f} "
                     f"| {gap[1]:+.2f} |" + (f" {gap[3]:+.2f} |" if args.long_ms else ""))
        print(lines[-1], file=sys.stderr, flush=True)
    lines.append("")
    for key, label in (("quick", "quick plan"), ("default", "default plan"), ("long", "longer search")):
        if gaps[key]:
            lines.append(f"- {label} vs the 3 s search over {len(gaps[key])} random instances: mean "
                         f"{statistics.mean(gaps[key]):+.2f} %, worst {max(gaps[key]):+.2f} %")
    if table_default is not None:
        lines.append(f"- Table 4.3, default plan: {table_default:.2f} s (target ≤ 40.2 s)")
    text = "\n".join(lines)
    print(text)
    return text


if __name__ == "__main__":
    main()
