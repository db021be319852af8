"""The quick plans' CPU time against another checkout, interleaved (a busy machine's before/after).

``bench/scaling.py --speed --before`` compares two runs made at different times; on a shared
machine their load differs and so does the CPU time of the same work (caches, the other hyper
thread). Here two worker processes, one importing this checkout's ``planners`` and one another
checkout's, plan the same instances (bench/scaling.py's: deployment and collection, ranges 5–20 m)
in turn, alternating which goes first; per instance the least CPU time of ``--reps`` runs, then the
median over ``--seeds`` instances, the mean makespans and the growth exponent from 100 to 1000.

Run: ``python bench/speed_ab.py --against /path/to/older/checkout [--seeds 5] [--reps 3]``
(prints markdown; of the other checkout only ``planners/`` is used: the instances are this one's).
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import math
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
SIZES = (10, 20, 50, 100, 200, 500, 1000)
KINDS = ("deploy", "collect")


def worker(root: str) -> None:
    """Plan ``kind n seed`` lines from stdin with ``root``'s planners; print CPU ms and makespan."""
    sys.path.insert(0, root)
    planners = importlib.import_module("planners")  # first: bench/scaling.py then finds it imported
    spec = importlib.util.spec_from_file_location("scaling", ROOT / "bench" / "scaling.py")
    assert spec is not None and spec.loader is not None
    scaling = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(scaling)
    fns = {"deploy": planners.DEPLOY_PLANNERS["lee"], "collect": planners.COLLECT_PLANNERS["lee"]}
    for kind, fn in fns.items():  # the planners' modules are imported on the first call: not timed
        fn(scaling._problem(kind, 10, 0))
    print("ready", flush=True)
    for line in sys.stdin:
        kind, n, seed = line.split()
        problem = scaling._problem(kind, int(n), int(seed))
        t0 = time.process_time()
        plan = fns[kind](problem)
        print(f"{(time.process_time() - t0) * 1e3:.3f} {plan.makespan!r}", flush=True)


def compare(other: str, seeds: int, reps: int) -> dict[str, dict[str, list[tuple[float, float]]]]:
    """Per side (this, other) and ``kind n``: per seed (least CPU ms, makespan)."""
    sides = {"before": other, "after": str(ROOT)}
    procs = {k: subprocess.Popen([sys.executable, __file__, "--worker", r], stdin=subprocess.PIPE,
                                 stdout=subprocess.PIPE, text=True) for k, r in sides.items()}
    for p in procs.values():
        assert p.stdout is not None and p.stdout.readline().strip() == "ready"
    out: dict[str, dict[str, list[tuple[float, float]]]] = {k: {} for k in sides}
    for kind in KINDS:
        for n in SIZES:
            for seed in range(seeds):
                best = {k: (math.inf, math.nan) for k in sides}
                for rep in range(reps):
                    for k in (("before", "after") if rep % 2 == 0 else ("after", "before")):
                        p = procs[k]
                        assert p.stdin is not None and p.stdout is not None
                        p.stdin.write(f"{kind} {n} {seed}\n")
                        p.stdin.flush()
                        ms, makespan = p.stdout.readline().split()
                        best[k] = (min(best[k][0], float(ms)), float(makespan))
                for k in sides:
                    out[k].setdefault(f"{kind} {n}", []).append(best[k])
    for p in procs.values():
        assert p.stdin is not None
        p.stdin.close()
        p.wait()
    return out


def table(res: dict[str, Any], seeds: int, reps: int) -> str:
    rows = []
    for kind in KINDS:
        rows += [f"### {kind}: CPU ms (per instance the least of {reps} runs, median of {seeds}), "
                 "mean makespan",
                 "", "| n | before ms | after ms | after / before | before makespan s | after makespan s |",
                 "|---|---|---|---|---|---|"]
        ms = {k: {n: statistics.median(v[0] for v in res[k][f"{kind} {n}"]) for n in SIZES} for k in res}
        for n in SIZES:
            mk = {k: statistics.mean(v[1] for v in res[k][f"{kind} {n}"]) for k in res}
            rows.append(f"| {n} | {ms['before'][n]:.1f} | {ms['after'][n]:.1f} | "
                        f"{ms['after'][n] / ms['before'][n]:.2f} | {mk['before']:.2f} | {mk['after']:.2f} |")
        grow = {k: math.log10(ms[k][1000] / ms[k][100]) for k in ms}
        rows += ["", f"Growth exponent 100 → 1000: {grow['after']:.2f} (before {grow['before']:.2f})", ""]
    return "\n".join(rows)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--against", help="the other checkout (its planners are 'before')")
    ap.add_argument("--seeds", type=int, default=5, help="instances per kind and size")
    ap.add_argument("--reps", type=int, default=3, help="runs per instance and side (the least counts)")
    ap.add_argument("--worker", metavar="ROOT", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        worker(args.worker)
    elif args.against:
        print(table(compare(args.against, args.seeds, args.reps), args.seeds, args.reps))
    else:
        ap.error("--against is required")
