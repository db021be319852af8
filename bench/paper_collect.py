"""The dissertation's collection scenarios (ch. 5.5, missions/paper/collect_*.yaml): reported figures
next to ours for every collection planner, the lower bound and compute times.

Run: ``python bench/paper_collect.py`` (prints markdown). ``main()`` returns the same markdown.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from fleetctl.mission import load_mission  # noqa: E402
from planners import COLLECT_PLANNERS, collect_lower_bound  # noqa: E402
from planners.core.timing import dissertation_model  # noqa: E402  (the paper tables use the text's time model)

NAMES = ("lee", "lee-convex", "visit-all", "gather")


def _reported(path: Path) -> str:
    """The 'Reported result:' sentence of the scenario file's header comment."""
    text = []
    for line in path.read_text().splitlines():
        if not line.startswith("#"):
            break
        text.append(line.lstrip("# ").strip())
    m = re.search(r"Reported result: (.*?)(?<!Fig)\.(?:\s|$)", " ".join(text))
    return m.group(1) if m else "-"


def main() -> str:
    files = sorted((ROOT / "missions" / "paper").glob("collect_*.yaml")) + [ROOT / "missions" / "recon.yaml"]
    out = ["## Collection scenarios (dissertation ch. 5.5)", "",
           "Each planner cell: makespan s / carrier distance m / stops. LB = `collect_lower_bound`. "
           "Times are wall-clock compute of one run.", "",
           "| scenario | reported | " + " | ".join(NAMES) + " | LB s | lee ms | lee-convex ms |",
           "|---|---|" + "---|" * len(NAMES) + "---|---|---|"]
    for path in files:
        problem = dissertation_model(load_mission(path).collect_problem())
        cells, ms = [], {}
        for name in NAMES:
            plan = COLLECT_PLANNERS[name](problem)
            cells.append(f"{plan.makespan:.2f} / {plan.carrier_distance:.2f} / {len(plan.stops)}")
            ms[name] = plan.compute_ms
        lb = collect_lower_bound(problem)
        reported = _reported(path) if path.parent.name == "paper" else "(our recon mission)"
        out.append(f"| {path.stem} | {reported} | " + " | ".join(cells)
                   + f" | {lb:.2f} | {ms['lee']:.1f} | {ms['lee-convex']:.1f} |")
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    print(main())
