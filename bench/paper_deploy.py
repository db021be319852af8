"""The dissertation's deployment scenarios (ch. 4.5): reported figures vs our planners.

Run: python bench/paper_deploy.py   (prints a markdown table)
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fleetctl.mission import load_mission  # noqa: E402
from planners import DEPLOY_PLANNERS, deploy_lower_bound  # noqa: E402
from planners.core.timing import dissertation_model  # noqa: E402  (the paper tables use the text's time model)

# file → (what the dissertation reports: makespan s, carrier distance m), None where not given
REPORTED = {
    "deploy_2tasks.yaml": ("Table 4.2 / Fig. 4.8", None, None),
    "deploy_15tasks_d25.yaml": ("Table 4.3 / Fig. 4.10a, d=25", 47.02, 157.52),
    "deploy_15tasks_d20.yaml": ("Fig. 4.10b, d=20", 54.52, None),
    "deploy_15tasks_d15.yaml": ("Fig. 4.10c, d=15", None, None),
    "deploy_15tasks_d10.yaml": ("Fig. 4.10d, d=10", None, 229.01),
    "deploy_2tasks_3d.yaml": ("Table 4.4 / Fig. 4.12 (3D)", None, None),
    "deploy_6tasks_3d_d7.yaml": ("Table 4.5 / Fig. 4.13a, d=7 (3D)", 52.95, 201.24),
    "deploy_6tasks_3d_d15.yaml": ("Fig. 4.13b, d=15 (3D)", None, None),
    "deploy_6tasks_3d_d25.yaml": ("Fig. 4.13c, d=25 (3D)", None, None),
}


def _fmt(v: float | None, unit: str = "") -> str:
    return "—" if v is None else f"{v:.2f}{unit}"


def _timed(fn, problem, repeats: int = 7):
    times = []
    plan = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        plan = fn(problem)
        times.append((time.perf_counter() - t0) * 1e3)
    return plan, statistics.median(times)


def main() -> str:
    rows = ["| scenario | reported s / m | lee s / m (stops) | greedy2opt s / m | lower bound s "
            "| lee vs reported | lee ms |",
            "|---|---|---|---|---|---|---|"]
    for name, (label, rep_t, rep_d) in REPORTED.items():
        problem = dissertation_model(load_mission(ROOT / "missions" / "paper" / name).deploy_problem())
        lee, lee_ms = _timed(DEPLOY_PLANNERS["lee"], problem)
        greedy = DEPLOY_PLANNERS["greedy2opt"](problem)
        lb = deploy_lower_bound(problem)
        delta = "—" if rep_t is None else f"{(lee.makespan - rep_t) / rep_t * 100:+.1f} %"
        rows.append(f"| {label} | {_fmt(rep_t)} / {_fmt(rep_d)} "
                    f"| {lee.makespan:.2f} / {lee.carrier_distance:.2f} ({len(lee.stops)}) "
                    f"| {greedy.makespan:.2f} / {greedy.carrier_distance:.2f} | {lb:.2f} | {delta} "
                    f"| {lee_ms:.1f} |")
    return "\n".join(rows)


if __name__ == "__main__":
    print(main())
