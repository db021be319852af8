"""Draw a plan with matplotlib (``fleetctl plan --plot OUT.png``)."""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402
from matplotlib.patches import Circle  # noqa: E402
from matplotlib.patches import Polygon as PolygonPatch  # noqa: E402

from fleetctl.mission import Mission  # noqa: E402
from planners.core.plan import Plan, RoverLeg, Stop  # noqa: E402

Colour = tuple[float, float, float, float]  # a colour of the colour map (RGBA)


def plot_plan(mission: Mission, plan: Plan, out: str | Path, lower_bound: float | None = None) -> Path:
    """Top view (and a side view when anything flies above the ground) of a deploy or collect plan.

    Deploy: tasks, stops, carrier route, rover flights, d_deploy circles around the stops.
    Collect: rovers, their reach circles on the ground, meeting points, carrier route, rover
    flights; one colour per stop (cluster).
    """
    out = Path(out)
    legs = plan.legs()
    heights = [p[2] for leg in legs for p in leg.path]
    three_d = any(abs(z) > 1e-9 for z in heights)
    if three_d:
        fig, (ax, side) = plt.subplots(1, 2, figsize=(15, 7.5), gridspec_kw={"width_ratios": [3, 2]})
    else:
        fig, ax = plt.subplots(figsize=(9, 9))
        side = None
    cmap = plt.get_cmap("tab10" if len(plan.stops) <= 10 else "tab20")
    _draw_world(ax, mission, plan)
    _draw_route(ax, plan)
    reach = {r.id: r.range for r in (mission.collection or ())}
    for k, stop in enumerate(plan.stops):
        colour = cmap(k % cmap.N)
        _draw_stop(ax, k, stop, colour, mission.rovers.deploy_range if plan.kind == "deploy" else None)
        for leg in stop.rovers:
            _draw_leg(ax, side, plan.kind, leg, colour, three_d, reach)
        if side is not None:
            side.plot(stop.position[0], 0.0, marker="D", color=colour, mec="black", ls="none")
    _label(ax, side, mission, plan, lower_bound)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def _draw_world(ax: Axes, mission: Mission, plan: Plan) -> None:
    """Obstacles, the roadmap of a ch. 6 planner (light, under everything else), the bounds."""
    for poly in mission.obstacles:
        ax.add_patch(PolygonPatch(poly, closed=True, facecolor="0.6", edgecolor="0.3", alpha=0.6))
    rm = getattr(plan, "roadmap", None)
    if rm is not None:
        xy = rm.xy
        ax.add_collection(LineCollection(xy[rm.edges()], colors="0.85", linewidths=0.3, zorder=0))
        ax.plot(xy[:, 0], xy[:, 1], ".", color="0.7", ms=1.5, zorder=0,
                label=f"roadmap ({rm.n_nodes} nodes, {rm.n_edges} edges)")
    if mission.bounds is not None:
        (x0, y0), (x1, y1) = mission.bounds
        ax.plot([x0, x1, x1, x0, x0], [y0, y0, y1, y1, y0], color="0.8", lw=0.8)


def _draw_route(ax: Axes, plan: Plan) -> None:
    """The carrier's route from its start (with its heading) through every stop."""
    route_x = [plan.start[0]]
    route_y = [plan.start[1]]
    for stop in plan.stops:
        for p in stop.carrier_path[1:]:
            route_x.append(p[0])
            route_y.append(p[1])
    ax.plot(route_x, route_y, "-", color="black", lw=2.0, label="carrier route", zorder=3)
    ax.plot(*plan.start[:2], marker="s", color="black", ms=10, ls="none", label="carrier start", zorder=4)
    tip = (plan.start[0] + 4 * math.cos(plan.heading), plan.start[1] + 4 * math.sin(plan.heading))
    ax.annotate("", xy=tip, xytext=plan.start[:2], arrowprops={"arrowstyle": "->", "color": "black"})


def _draw_stop(ax: Axes, k: int, stop: Stop, colour: Colour, deploy_range: float | None) -> None:
    """Stop ``k`` (numbered from 1) and, for a deployment, the rovers' range around it."""
    sx, sy = stop.position[0], stop.position[1]
    ax.plot(sx, sy, marker="D", color=colour, ms=9, mec="black", ls="none", zorder=5,
            label="stops" if k == 0 else None)
    ax.annotate(f"{k + 1}", (sx, sy), textcoords="offset points", xytext=(6, 6), fontsize=9, weight="bold")
    if deploy_range is not None:
        ax.add_patch(Circle((sx, sy), deploy_range, fill=False, ls=":", color=colour, lw=1))


def _draw_leg(ax: Axes, side: Axes | None, kind: str, leg: RoverLeg, colour: Colour, three_d: bool,
              reach: dict[str, float]) -> None:
    """A rover's flight: to its task (deploy) or from where it is, with its reach (collect)."""
    ax.plot([p[0] for p in leg.path], [p[1] for p in leg.path], "--", color=colour, lw=1.2, zorder=2)
    if kind == "deploy":
        tx, ty, tz = leg.end
        ax.plot(tx, ty, marker="o", color=colour, ms=7, mec="black", ls="none", zorder=4)
        label = f"{leg.task}" + (f" ({tz:g} m)" if three_d else "")
        ax.annotate(label, (tx, ty), textcoords="offset points", xytext=(4, -10), fontsize=7)
    else:
        fx, fy, fz = leg.start
        ax.plot(fx, fy, marker="^", color=colour, ms=7, mec="black", ls="none", zorder=4)
        ax.annotate(leg.rover, (fx, fy), textcoords="offset points", xytext=(4, -10), fontsize=7)
        if leg.rover in reach:
            ground = math.sqrt(max(reach[leg.rover] ** 2 - fz**2, 0.0))
            ax.add_patch(Circle((fx, fy), ground, fill=False, ls=":", color=colour, lw=1))
    if side is not None:
        side.plot([p[0] for p in leg.path], [p[2] for p in leg.path], "--", color=colour, lw=1.2)
        end = leg.end if kind == "deploy" else leg.start
        side.plot(end[0], end[2], marker="o" if kind == "deploy" else "^", color=colour,
                  mec="black", ls="none")


def _label(ax: Axes, side: Axes | None, mission: Mission, plan: Plan, lower_bound: float | None) -> None:
    """The title (makespan, distance, stops, the lower bound), axes, grid and legend."""
    what = "deployment" if plan.kind == "deploy" else "collection"
    title = (f"{mission.name}: {what} by {plan.planner} — makespan {plan.makespan:.2f} s, "
             f"carrier {plan.carrier_distance:.1f} m, {len(plan.stops)} stops")
    if lower_bound is not None:
        title += f" (lower bound {lower_bound:.2f} s)"
    ax.set_title(title, fontsize=10)
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, color="0.92")
    ax.legend(loc="best", fontsize=8)
    if side is not None:
        side.set_title("side view (east vs height)", fontsize=10)
        side.set_xlabel("east (m)")
        side.set_ylabel("height (m)")
        side.axhline(0.0, color="0.5", lw=0.8)
        side.grid(True, color="0.92")
