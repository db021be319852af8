"""Chapter 6.5 environments: roadmap size, deployment makespan with and without local PRM, compute time.

Compares with Tables 6.1, 6.3, 6.4, 6.6, 6.8 and the reported deployment times. Writes a markdown
table to stdout (and to ``--out`` if given). Usage: ``python bench/paper_roadmap.py [--seeds N]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fleetctl.mission import load_mission  # noqa: E402
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


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seeds", type=int, default=5, help="roadmap seeds per environment (median reported)")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    rows = ["| environment | global PRM nodes / edges (paper) | after local PRM (paper) | makespan s "
            "(paper) | without local PRM s (paper) | collect s | plan ms (max) |",
            "|---|---|---|---|---|---|---|"]
    for name, (g_paper, l_paper, m_paper, m0_paper) in PAPER.items():
        m = load_mission(ROOT / "missions" / "paper" / f"{name}.yaml")
        dp, cp = dissertation_model(m.deploy_problem()), dissertation_model(m.collect_problem())
        g, loc, ms, ms0, mc, cpu = [], [], [], [], [], []
        for seed in range(args.seeds):
            t0 = time.perf_counter()
            plan = plan_lee_graph(dataclasses.replace(dp, seed=seed))
            cpu.append((time.perf_counter() - t0) * 1e3)
            rm = plan.roadmap
            g.append((rm.global_nodes, rm.global_edges))
            loc.append((rm.n_nodes, rm.n_edges))
            ms.append(plan.makespan)
            ms0.append(plan_lee_graph(dataclasses.replace(dp, seed=seed), local_prm=False).makespan)
            mc.append(plan_collect_lee_graph(dataclasses.replace(cp, seed=seed)).makespan)

        def nodes_edges(pairs: list[tuple[int, int]]) -> str:
            return (f"{statistics.median(p[0] for p in pairs):.0f} / "
                    f"{statistics.median(p[1] for p in pairs):,.0f}")

        span = f"{statistics.median(ms):.2f} [{min(ms):.2f}–{max(ms):.2f}]"
        rows.append(f"| {name} (d={m.rovers.deploy_range:g} m) | {nodes_edges(g)} ({g_paper}) | "
                    f"{nodes_edges(loc)} ({l_paper}) | {span} ({m_paper}) | "
                    f"{statistics.median(ms0):.2f} ({m0_paper}) | {statistics.median(mc):.2f} | "
                    f"{max(cpu):.0f} |")
    text = "\n".join(rows) + "\n"
    sys.stdout.write(text)
    if args.out:
        args.out.write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
