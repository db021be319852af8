"""Planner speed and plan quality at scale (dissertation ch. 4.6, ch. 5.6).

1. ``lee`` deployment compute time for n = 10 … 1000 random tasks in a 200 m square (ch. 4.6.1:
   d_deploy 5–20 m; v_c, w_c, a_c, t_u, v_r normal around 15 m/s, 3 rad/s, 5 m/s², 3 s, 3 m/s).
2. Mean makespan improvement of ``lee`` over ``greedy2opt`` on the Monte Carlo setup of
   ch. 4.6.2 (300 m square, n = 10 … 100, d_deploy = 10 … 40 m).
3. The collection tables of bench/scaling_collect.py when it is present.

With ``--speed``, instead: the quick plans' CPU time (median over ``--seeds`` instances) of deployment
(bench/scaling.py's instances) and collection (bench/scaling_collect.py's, ranges 5–20 m) for
n = 10 … 1000, their mean makespans, the growth exponent from 100 to 1000 and the targets (deploy
100 ≤ 10 ms, 1000 ≤ 100 ms; collect 100 ≤ 20 ms, 1000 ≤ 150 ms; the exponent ≤ 1.2); and a replan
in flight at 100 tasks (rovers) as ``fleetctl.run`` makes it (the carrier part-way along, one task
removed and one added / one rover lost; the quick plan, and a named budget capped as replans are).
``--save FILE`` keeps the numbers (JSON); ``--before FILE`` prints them beside the current ones.
Run the same script inside an older checkout with ``--save`` to get the "before".

Run: python bench/scaling.py [--reps N]   (prints markdown tables)
     python bench/scaling.py --speed [--seeds 5] [--save F] [--before F]
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import json
import math
import random
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from planners import COLLECT_PLANNERS, DEPLOY_PLANNERS  # noqa: E402
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


SPEED_SIZES = (10, 20, 50, 100, 200, 500, 1000)
TARGET_MS = {("deploy", 100): 10.0, ("deploy", 1000): 100.0, ("collect", 100): 20.0, ("collect", 1000): 150.0}


def _collect_problems() -> Any:
    spec = importlib.util.spec_from_file_location("scaling_collect", ROOT / "bench" / "scaling_collect.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _cpu(fn: Callable[[Any], Any], problem: Any) -> tuple[float, float]:
    t0 = time.process_time()  # CPU time: steadier than wall time on a busy machine
    plan = fn(problem)
    return (time.process_time() - t0) * 1e3, plan.makespan


def _problem(kind: str, n: int, seed: int) -> Any:
    if kind == "deploy":
        rng = random.Random(1000 * n + seed)
        return random_deploy(rng, n, 200.0, rng.uniform(5.0, 20.0))
    return _collect_problems().random_problem(n, 1000 * n + seed, 200.0, ranges=(5.0, 20.0))


def speed(seeds: int) -> dict[str, Any]:
    """CPU ms (median) and mean makespan of the quick plans per kind and size, and replans."""
    out: dict[str, Any] = {}
    for kind, fn in (("deploy", DEPLOY_PLANNERS["lee"]), ("collect", COLLECT_PLANNERS["lee"])):
        for n in SPEED_SIZES:
            runs = [_cpu(fn, _problem(kind, n, s)) for s in range(seeds)]
            out[f"{kind} {n}"] = {"ms": statistics.median(r[0] for r in runs),
                                  "makespan": statistics.mean(r[1] for r in runs)}
    out.update(replans(seeds))
    return out


def _replan_cap() -> float:
    try:
        from fleetctl.run.budget import REPLAN_BUDGET_MS
    except ImportError:  # an older checkout
        from fleetctl.run.planning import REPLAN_BUDGET_MS
    return float(REPLAN_BUDGET_MS)


def replans(seeds: int, n: int = 100) -> dict[str, Any]:
    """A replan in flight at ``n`` tasks (rovers), as ``fleetctl.run``'s phases make it: deployment
    from a point part-way along the route with one task removed and one added (``tasks changed``);
    collection of the rovers left after one is lost, from the carrier part-way along. The quick
    plan (no budget named) and a named budget (capped at the replan cap)."""
    out: dict[str, Any] = {}
    cap = _replan_cap()
    for kind, fn in (("deploy", DEPLOY_PLANNERS["lee"]), ("collect", COLLECT_PLANNERS["lee"])):
        fn(_problem(kind, 10, 0))  # the planner's modules are imported on its first call: not timed
        for label, budget in (("quick", None), (f"budget {cap:.0f} ms", cap)):
            ms = []
            for s in range(seeds):
                p = _problem(kind, n + 1, s)
                rng = random.Random(s)
                mid = (rng.uniform(50.0, 150.0), rng.uniform(50.0, 150.0), 0.0)
                if kind == "deploy":
                    tasks = (*p.tasks[1:], dataclasses.replace(p.tasks[0], position=(100.0, 100.0, 0.0)))
                    p = dataclasses.replace(p, start=mid, tasks=tasks[:n], budget_ms=budget)
                else:
                    p = dataclasses.replace(p, start=mid, rovers=p.rovers[1:], budget_ms=budget)
                ms.append(_cpu(fn, p)[0])
            out[f"replan {kind} {n} {label}"] = {"ms": statistics.median(ms), "max": max(ms)}
    return out


def speed_tables(now: dict[str, Any], before: dict[str, Any] | None) -> str:
    def exponent(d: dict[str, Any], kind: str) -> float:
        return math.log(d[f"{kind} 1000"]["ms"] / d[f"{kind} 100"]["ms"]) / math.log(10.0)

    rows = []
    for kind in ("deploy", "collect"):
        head = "| n | " + ("before CPU ms | " if before else "") + "CPU ms | target ms | " + (
            "before makespan s | " if before else "") + "makespan s |"
        rows += [f"### {kind}: quick plan CPU time (median of the seeds) and mean makespan", "", head,
                 "|---" * (head.count("|") - 1) + "|"]
        for n in SPEED_SIZES:
            k = f"{kind} {n}"
            target = TARGET_MS.get((kind, n))
            cells = [str(n)]
            if before:
                cells.append(f"{before[k]['ms']:.1f}")
            cells += [f"{now[k]['ms']:.1f}", "—" if target is None else f"≤ {target:.0f}"]
            if before:
                cells.append(f"{before[k]['makespan']:.2f}")
            cells.append(f"{now[k]['makespan']:.2f}")
            rows.append("| " + " | ".join(cells) + " |")
        rows.append("")
        rows.append(f"Growth exponent 100 → 1000: {exponent(now, kind):.2f}"
                    + (f" (before {exponent(before, kind):.2f})" if before else "") + " (target ≤ 1.2)")
        rows.append("")
    rows += ["### replans in flight (100 tasks / rovers): CPU ms, median and worst", "",
             "| replan | " + ("before | " if before else "") + "CPU ms (median / worst) | target |",
             "|---|" + ("---|" if before else "") + "---|---|"]
    for k, v in now.items():
        if k.startswith("replan"):
            old = before.get(k) if before else None
            cells = [k.removeprefix("replan ")]
            if before:
                cells.append("—" if old is None else f"{old['ms']:.1f} / {old['max']:.1f}")
            cells += [f"{v['ms']:.1f} / {v['max']:.1f}", "≤ 50"]
            rows.append("| " + " | ".join(cells) + " |")
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
    ap.add_argument("--speed", action="store_true", help="the quick plans' CPU time and replans (see above)")
    ap.add_argument("--seeds", type=int, default=5, help="--speed: instances per size")
    ap.add_argument("--save", metavar="FILE", help="--speed: keep the numbers as JSON")
    ap.add_argument("--before", metavar="FILE", help="--speed: numbers of an older checkout to print beside")
    args = ap.parse_args()
    if args.speed:
        numbers = speed(args.seeds)
        if args.save:
            Path(args.save).write_text(json.dumps(numbers, indent=1), encoding="utf-8")
        before = json.loads(Path(args.before).read_text(encoding="utf-8")) if args.before else None
        print(speed_tables(numbers, before))
    else:
        print(main(args.reps))
