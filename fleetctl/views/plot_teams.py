"""Draw a several-team plan (``fleetctl plan --plot OUT.png`` on a ``carriers:`` mission): every team
in its own colour — its carrier's start and route, its stops, its rovers' flights and tasks."""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402
from matplotlib.patches import Polygon as PolygonPatch  # noqa: E402

from fleetctl.mission import Mission  # noqa: E402
from planners.core.plan import Plan  # noqa: E402
from planners.teams import TeamsPlan  # noqa: E402


def plot_teams(mission: Mission, plan: TeamsPlan, out: str | Path, lower_bound: float | None = None) -> Path:
    """Top view of every team's plan, one colour per team."""
    out = Path(out)
    fig, ax = plt.subplots(figsize=(10, 9))
    for poly in mission.obstacles:
        ax.add_patch(PolygonPatch(poly, closed=True, facecolor="0.6", edgecolor="0.3", alpha=0.6))
    if mission.bounds is not None:
        (x0, y0), (x1, y1) = mission.bounds
        ax.plot([x0, x1, x1, x0, x0], [y0, y0, y1, y1, y0], color="0.8", lw=0.8)
    cmap = plt.get_cmap("tab10")
    for k, team in enumerate(plan.teams):
        _draw_team(ax, team.carrier, team.plan, cmap(k % cmap.N))
    what = "deployment" if plan.kind == "deploy" else "collection"
    title = (f"{mission.name}: {what} by {len(plan.teams)} teams ({plan.planner}) — makespan "
             f"{plan.makespan:.2f} s")
    if plan.baseline_makespan is not None:
        title += f", nearest carrier {plan.baseline_makespan:.2f} s"
    if lower_bound is not None:
        title += f"\nlower bound {lower_bound:.2f} s"
    ax.set_title(title, fontsize=10)
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, color="0.92")
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def _draw_team(ax: Axes, carrier: str, plan: Plan, colour: object) -> None:
    xs, ys = [plan.start[0]], [plan.start[1]]
    for stop in plan.stops:
        xs += [p[0] for p in stop.carrier_path[1:]]
        ys += [p[1] for p in stop.carrier_path[1:]]
    ax.plot(xs, ys, "-", color=colour, lw=2.2, zorder=3,
            label=f"{carrier}: {plan.makespan:.1f} s, {len(plan.legs())} rovers")
    ax.plot(*plan.start[:2], marker="s", color=colour, mec="black", ms=11, ls="none", zorder=4)
    ax.annotate(carrier, plan.start[:2], textcoords="offset points", xytext=(6, -14), fontsize=9,
                weight="bold")
    tip = (plan.start[0] + 6 * math.cos(plan.heading), plan.start[1] + 6 * math.sin(plan.heading))
    ax.annotate("", xy=tip, xytext=plan.start[:2], arrowprops={"arrowstyle": "->", "color": "black"})
    for n, stop in enumerate(plan.stops, 1):
        ax.plot(stop.position[0], stop.position[1], marker="D", color=colour, mec="black", ms=8, ls="none",
                zorder=5)
        ax.annotate(str(n), stop.position[:2], textcoords="offset points", xytext=(5, 5), fontsize=8)
        for leg in stop.rovers:
            ax.plot([p[0] for p in leg.path], [p[1] for p in leg.path], "--", color=colour, lw=1.0, zorder=2)
            end = leg.end if plan.kind == "deploy" else leg.start
            ax.plot(end[0], end[1], marker="o" if plan.kind == "deploy" else "^", color=colour, mec="black",
                    ms=6, ls="none", zorder=4)
            ax.annotate(leg.task if plan.kind == "deploy" and leg.task else leg.rover, end[:2],
                        textcoords="offset points", xytext=(4, -10), fontsize=7)
