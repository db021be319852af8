"""Chapter 6.5 environments: roadmap size, deployment makespan with and without local PRM, compute time.

Compares with Tables 6.1, 6.3, 6.4, 6.6, 6.8 and the reported deployment times. ``lee-graph`` is
Algorithm 6.3 followed by the search (planners/roadmap/search.py); the columns "Algorithm 6.3
alone" are the same planner with ``search=False``, the dissertation's algorithm (its roadmap is
the one the node and edge columns count). CPU milliseconds are process time. Writes a markdown
table to stdout (and to ``--out`` if given). Usage: ``python bench/paper_roadmap.py [--seeds N]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fleetctl.mission import load_mission  # noqa: E402
from planners.core.plan import Plan  # noqa: E402
from planners.core.timing import dissertation_model  # noqa: E402  (the paper tables use the text's time model)
from planners.roadmap.collect import plan_collect_lee_graph  # noqa: E402
from planners.roadmap.deploy import plan_lee_graph  # noqa: E402

# file: reported global nodes/edges, after-local nodes/edges, makespan with / without local PRM
PAPER = {
    "roadmap_outdoor": ("300 / 2,761", "393 / 6,238", "27.14", "27.58"),
    "roadmap_outdoor_obstacles": ("300 / 2,594", "424 / 6,857", "33.25", "-"),
    "roadmap_office": ("190 / 1,659", "254 / 3,385", "24.25", "-"),
    "roadmap_university": ("220 / 1,248", "419 / 5,368", "45.25", "-"),
}


def _timed(planner: Callable[..., Plan], problem: Any, **kw: Any) -> tuple[Plan, float]:
    """The plan and the CPU milliseconds it took (process time: steadier on a shared machine)."""
    t0 = time.process_time()
    plan = planner(problem, **kw)
    return plan, (time.process_time() - t0) * 1e3


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seeds", type=int, default=5, help="roadmap seeds per environment (median reported)")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    rows = ["| environment | global PRM nodes / edges (paper) | after local PRM (paper) | makespan s "
            "(paper) | Algorithm 6.3 alone s | without local PRM s (paper) | collect s (Alg. 6.3 alone) | "
            "plan ms (max) | Alg. 6.3 ms (max) | collect ms (Alg. 6.3) |",
            "|---|---|---|---|---|---|---|---|---|---|"]
    for name, (g_paper, l_paper, m_paper, m0_paper) in PAPER.items():
        m = load_mission(ROOT / "missions" / "paper" / f"{name}.yaml")
        dp, cp = dissertation_model(m.deploy_problem()), dissertation_model(m.collect_problem())
        g, loc, ms, ms_g, ms0, mc, mc_g = [], [], [], [], [], [], []
        cpu, cpu_g, cpu_c, cpu_cg = [], [], [], []
        for seed in range(args.seeds):
            dps, cps = dataclasses.replace(dp, seed=seed), dataclasses.replace(cp, seed=seed)
            plan, ms_cpu = _timed(plan_lee_graph, dps)
            greedy, g_cpu = _timed(plan_lee_graph, dps, search=False)  # the dissertation's algorithm
            cpu.append(ms_cpu)
            cpu_g.append(g_cpu)
            rm = greedy.roadmap  # the roadmap of Algorithm 6.3 (the search adds nodes near its stops)
            g.append((rm.global_nodes, rm.global_edges))
            loc.append((rm.n_nodes, rm.n_edges))
            ms.append(plan.makespan)
            ms_g.append(greedy.makespan)
            ms0.append(plan_lee_graph(dps, local_prm=False).makespan)
            col, c_cpu = _timed(plan_collect_lee_graph, cps)
            col_g, cg_cpu = _timed(plan_collect_lee_graph, cps, search=False)
            mc.append(col.makespan)
            mc_g.append(col_g.makespan)
            cpu_c.append(c_cpu)
            cpu_cg.append(cg_cpu)

        def nodes_edges(pairs: list[tuple[int, int]]) -> str:
            return (f"{statistics.median(p[0] for p in pairs):.0f} / "
                    f"{statistics.median(p[1] for p in pairs):,.0f}")

        span = f"{statistics.median(ms):.2f} [{min(ms):.2f}–{max(ms):.2f}]"
        span_g = f"{statistics.median(ms_g):.2f} [{min(ms_g):.2f}–{max(ms_g):.2f}]"
        rows.append(f"| {name} (d={m.rovers.deploy_range:g} m) | {nodes_edges(g)} ({g_paper}) | "
                    f"{nodes_edges(loc)} ({l_paper}) | {span} ({m_paper}) | {span_g} | "
                    f"{statistics.median(ms0):.2f} ({m0_paper}) | {statistics.median(mc):.2f} "
                    f"({statistics.median(mc_g):.2f}) | {max(cpu):.0f} | {max(cpu_g):.0f} | "
                    f"{max(cpu_c):.0f} ({max(cpu_cg):.0f}) |")
    text = "\n".join(rows) + "\n"
    sys.stdout.write(text)
    if args.out:
        args.out.write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
