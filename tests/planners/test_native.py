"""The compiled kernels (planners/core/_native_src/, planners.core.native) compute the floats of their
pure-Python twins, so that a plan does not depend on whether the install could compile them."""

from __future__ import annotations

import json
import math
import os
import random
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from planners.core.native import kernels

ROOT = Path(__file__).resolve().parents[2]
native = pytest.mark.skipif(kernels is None, reason="compiled kernels not built (no C compiler at install)")


def test_kernels_are_built_where_they_can_be() -> None:
    """Where a C compiler and Python's headers are, the install builds the kernels (an empty or
    failed build would otherwise only show as skipped tests)."""
    import shutil
    import sysconfig

    if os.environ.get("FLEETCTL_PURE_PYTHON", "") not in ("", "0"):
        pytest.skip("FLEETCTL_PURE_PYTHON turns the kernels off")
    headers = Path(sysconfig.get_paths()["include"]) / "Python.h"
    if shutil.which(os.environ.get("CC", "cc")) is None or not headers.exists():
        pytest.skip("no C compiler or no Python headers here: the planners run the Python code")
    assert kernels is not None, "a C compiler is here but planners.core._native is not built: reinstall"
    assert {"Stepper", "Circles", "route_times", "quickest"} <= set(dir(kernels))


@native
def test_the_stub_names_every_kernel() -> None:
    """planners/core/_native.pyi (what mypy reads) names exactly the module's functions and types."""
    import ast

    stub = ast.parse((ROOT / "planners" / "core" / "_native.pyi").read_text(encoding="utf-8"))
    named = {n.name for n in stub.body if isinstance(n, ast.FunctionDef | ast.ClassDef)}
    assert named == {name for name in dir(kernels) if not name.startswith("__")}


def test_the_readme_names_every_c_file() -> None:
    """The README's paragraph on the C twins names every file of planners/core/_native_src/."""
    import re

    text = (ROOT / "README.md").read_text(encoding="utf-8")
    named = set(re.findall(r"`(\w+\.[ch])`", text))
    folder = ROOT / "planners" / "core" / "_native_src"
    present = {p.name for p in folder.iterdir() if p.suffix in (".c", ".h")}
    assert named == present, (named, present)


@native
def test_step_hop_and_leg_kernels_give_the_python_floats() -> None:
    from planners.core.timing import _python_leg, _python_stepper

    assert kernels is not None
    rng = random.Random(5)
    for _ in range(200):
        v = rng.uniform(0.5, 25)
        a = rng.choice([None, rng.uniform(0.3, 10)])
        w = rng.choice([None, rng.uniform(0.1, 5)])
        fixed = rng.uniform(0, 4)
        step, py_step = kernels.Stepper(v, a, w), _python_stepper(v, a, w)
        hop = kernels.Hopper(v, a, w)
        leg, py_leg = kernels.Leg(v, a, fixed), _python_leg(v, a, fixed)
        for _ in range(50):
            length = rng.choice([0.0, 1e-10, rng.uniform(0, 2), rng.uniform(0, 200), v * v / a if a else 1.0])
            ang = rng.uniform(-math.pi, math.pi)
            dx, dy = length * math.cos(ang), length * math.sin(ang)
            h0 = rng.choice([ang, ang + math.pi, ang - math.pi, rng.uniform(-20, 20), 0.0, -0.0])
            assert step(dx, dy, h0) == py_step(dx, dy, h0)
            p = (rng.uniform(-100, 100), rng.uniform(-100, 100))
            assert hop(p, (p[0] + dx, p[1] + dy), h0) == py_step(p[0] + dx - p[0], p[1] + dy - p[1], h0)
            assert hop(np.array(p), [p[0] + dx, p[1] + dy], h0) == hop(p, (p[0] + dx, p[1] + dy), h0)
            assert leg(length) == py_leg(length) and leg(-length) == py_leg(-length)
    with pytest.raises(TypeError):
        kernels.Stepper(1.0, None, None)(1.0, 2.0)
    with pytest.raises(IndexError):  # (as the Python hop's q[1] - p[1])
        kernels.Hopper(1.0, None, None)((1.0,), (2.0, 3.0), 0.0)


@native
def test_farthest_flight_and_two_opt_kernels_match_python() -> None:
    from planners.collect.reach import farthest_flight
    from planners.core.routing import _two_opt_small, nearest_neighbour

    assert kernels is not None
    rng = np.random.default_rng(3)
    for k in (1, 2, 5, 13):
        rows = [tuple(map(float, r)) for r in rng.uniform(-30, 30, (k, 3))]
        for p in rng.uniform(-40, 40, (20, 2)).tolist():
            assert kernels.farthest_flight(rows, p) == farthest_flight(rows, p)
    for n in (1, 2, 3, 8, 30, 79):
        nodes = rng.uniform(0, 200, (n + 1, 2))
        dmat = np.linalg.norm(nodes[:, None, :] - nodes[None, :, :], axis=2)
        for route in (nearest_neighbour(dmat), [0, *rng.permutation(np.arange(1, n + 1)).tolist()]):
            assert kernels.two_opt_small(dmat, route) == _two_opt_small(dmat.tolist(), route)
    with pytest.raises(ValueError):
        kernels.two_opt_small(np.zeros((3, 3)), [0, 1])


@native
def test_hypot_kernel_is_pythons_math_hypot() -> None:
    assert kernels is not None
    rng = random.Random(8)
    odd = [0.0, -0.0, 5e-324, -1e-310, 1e-300, 1e300, 1.7e308, math.inf, -math.inf, 3.0, -4.0]
    for _ in range(100_000):
        x, y = rng.uniform(-400, 400), rng.uniform(-400, 400)
        assert kernels.hypot(x, y) == math.hypot(x, y)
    for x in odd:
        for y in odd:
            assert kernels.hypot(x, y) == math.hypot(x, y)
    assert math.isnan(kernels.hypot(math.nan, 1.0)) and kernels.hypot(math.nan, math.inf) == math.inf


@native
def test_projection_rim_and_clip_kernels_match_python() -> None:
    """Regions of random clusters: projections of points around them, every disc's rim and its
    vertex nearest to points, the vertices, segments."""
    from planners.collect.reach import (
        INSIDE_TOL,
        clip_segment,
        disc_vertices,
        project_discs,
        rim,
        vertex_on_rim,
    )

    assert kernels is not None
    rng = random.Random(9)
    seen = {"point": 0, "vertex": 0, "rim": 0, "clip": 0, "vertices": 0, "on rim": 0, "off rim": 0}
    for _ in range(400):
        k = rng.choice([1, 2, 3, 4, 6, 9, 40])
        cx, cy = rng.uniform(-50, 50), rng.uniform(-50, 50)
        discs = [(cx + rng.uniform(-12, 12), cy + rng.uniform(-12, 12), rng.uniform(4, 20)) for _ in range(k)]
        if rng.random() < 0.2:  # tangent and coincident circles
            discs.append((discs[0][0] + discs[0][2] * 2, discs[0][1], discs[0][2]))
            discs.append(discs[0])
        limits = [(x, y, (r + INSIDE_TOL) ** 2) for x, y, r in discs]
        for _ in range(15):
            x, y = cx + rng.uniform(-40, 40), cy + rng.uniform(-40, 40)
            got = kernels.project_discs(discs, limits, x, y)
            assert got == project_discs(discs, limits, x, y)
            seen["vertex" if isinstance(got, int) else "point"] += 1
            a, b = (x, y), (cx + rng.uniform(-40, 40), cy + rng.uniform(-40, 40))
            for end in (b, a):
                clip = kernels.clip_segment(discs, a, end)
                assert clip == clip_segment(discs, a, end)
                seen["clip"] += clip is not None
        for d in discs:
            got_rim = kernels.rim(d, discs, limits)
            assert got_rim == rim(d, discs, limits)
            assert all(o is p for (_, o), (_, p) in zip(got_rim, rim(d, discs, limits), strict=True))
            seen["rim"] += len(got_rim)
            for _ in range(5):
                x, y = cx + rng.uniform(-40, 40), cy + rng.uniform(-40, 40)
                vertex = kernels.vertex_on_rim(got_rim, d, x, y)
                assert vertex == vertex_on_rim(got_rim, d, x, y)
                seen["on rim" if vertex is not None else "off rim"] += 1
        vertices = kernels.disc_vertices(discs)
        assert vertices == disc_vertices(discs)
        seen["vertices"] += len(vertices)
    assert min(seen.values()) > 50, seen  # every branch was compared


@native
@pytest.mark.parametrize("grid", [False, True])
def test_enclosing_circles_kernel_matches_python(grid: bool) -> None:
    """Random walks of clusters (members added, removed, exchanged) over generic points, and over
    small grids squeezed to nearly collinear points (the degenerate fallback, counted)."""
    from planners.core.geometry import EnclosingCircles, _boundary_circle, _shuffled

    assert kernels is not None
    degenerate = []

    def fallback(pts: list, ws: list) -> tuple[float, float, float]:
        degenerate.append(1)
        return _boundary_circle(pts, ws)

    rng = random.Random(11 + grid)
    for _ in range(400 if grid else 4):
        if grid:
            k = rng.choice([2, 3, 5])
            pts = [(rng.randrange(k) * 0.1 + 1e-13 * rng.random(), float(rng.randrange(k)))
                   for _ in range(rng.randrange(2, 14))]
            w = [rng.choice([0.0, 0.25, 1.0, 4.0]) for _ in pts]
        else:
            pts = [(rng.uniform(-100, 100), rng.uniform(-100, 100)) for _ in range(40)]
            w = [rng.choice([0.0, rng.uniform(0, 400)]) for _ in pts]
        ours, ref = kernels.Circles(pts, fallback, _shuffled), EnclosingCircles(pts)
        cur = (0,)
        for _ in range(50 if grid else 300):
            s = set(cur)
            if rng.random() < 0.4 and len(s) > 1:
                s.discard(rng.choice(cur))
            if rng.random() > 0.3:
                s.add(rng.randrange(len(pts)))
            prev, cur = cur, tuple(sorted(s))
            weights = [w[i] for i in cur] if rng.random() < 0.7 else None
            near = rng.choice([(prev,), (prev, cur[1:]), ()])
            assert ours.get(cur, weights, near) == ref.get(cur, weights, near)
            assert ours.get(cur) == ref.get(cur)  # remembered
    assert (len(degenerate) > 5) if grid else not degenerate, len(degenerate)
    with pytest.raises(TypeError):
        ours.get([0, 1])
    with pytest.raises(IndexError):
        ours.get((0, len(pts)))
    with pytest.raises(ValueError):
        ours.get(())


@native
def test_welzl_and_deploy_reach_kernels_match_python() -> None:
    """Welzl's loop on random point sets (generic and squeezed nearly collinear: the fallback),
    and the deployment's longest flight from a ground point to a cluster."""
    from planners.core.geometry import _boundary_circle, _welzl_2d
    from planners.deploy.cluster import reach_of

    assert kernels is not None
    rng = random.Random(13)
    for _ in range(3000):
        n = rng.randrange(1, 30)
        squeeze = rng.random() < 0.5
        xs = [rng.randrange(4) * 0.1 + 1e-13 * rng.random() if squeeze else rng.uniform(-100, 100)
              for _ in range(n)]
        ys = [float(rng.randrange(4)) if squeeze else rng.uniform(-100, 100) for _ in range(n)]
        ws = [rng.choice([0.0, 0.25, 1.0, 4.0, rng.uniform(0, 300)]) for _ in range(n)]
        assert kernels.welzl_2d(xs, ys, ws, _boundary_circle) == _welzl_2d(xs, ys, ws)
        rows = list(zip(xs, ys, ws, strict=True))
        members = rng.sample(range(n), rng.randrange(0, n + 1))
        x, y = rng.uniform(-120, 120), rng.uniform(-120, 120)
        assert kernels.reach_of(rows, members, x, y) == reach_of(rows, members, x, y)
    with pytest.raises(ValueError):
        kernels.welzl_2d([], [], [], _boundary_circle)
    with pytest.raises(IndexError):
        kernels.reach_of([(0.0, 0.0, 0.0)], [1], 0.0, 0.0)


@native
def test_stop_cost_kernels_match_python() -> None:
    """The polishes' cost of one stop moved (deployment and collection) on random fixed data and
    points, with and without acceleration, turn rate, next stops; out of reach included."""
    from planners.collect.polish import collect_stop_cost
    from planners.core.timing import _python_leg, _python_stepper
    from planners.deploy.stops import deploy_stop_cost

    assert kernels is not None
    rng = random.Random(17)
    seen = {"inf": 0, "finite": 0}
    for _ in range(300):
        v, a = rng.uniform(2, 20), rng.choice([None, rng.uniform(0.5, 5)])
        w = rng.choice([None, rng.uniform(0.2, 3)])
        rv, ra, fixed = rng.uniform(2, 10), rng.choice([None, rng.uniform(0.5, 5)]), rng.uniform(0, 3)
        c_models = kernels.Stepper(v, a, w), kernels.Leg(rv, ra, fixed)
        py_models = _python_stepper(v, a, w), _python_leg(rv, ra, fixed)
        cx, cy = rng.uniform(-50, 50), rng.uniform(-50, 50)
        tasks = [(cx + rng.uniform(-15, 15), cy + rng.uniform(-15, 15), rng.uniform(0, 10) ** 2)
                 for _ in range(rng.randrange(1, 8))]
        start = (cx + rng.uniform(-80, 80), cy + rng.uniform(-80, 80), rng.uniform(-4, 4),
                 rng.uniform(0, 100))
        next1 = rng.choice([None, (cx + rng.uniform(-80, 80), cy + rng.uniform(-80, 80), rng.uniform(0, 200),
                                   rng.uniform(0, 200))])
        h12 = rng.choice([None, rng.uniform(-4, 4)])
        next2 = None if next1 is None else rng.choice(
            [None, (rng.uniform(0, 30), h12, rng.uniform(0, 100), rng.uniform(0, 200))])
        deploy = (tasks, rng.uniform(100, 900), start, rng.uniform(0, 5), rng.uniform(0, 150), next1, next2,
                  w)
        rows = [(x, y, rng.uniform(10, 20) ** 2, z2) for x, y, z2 in tasks]
        later = [(cx + rng.uniform(-80, 80), cy + rng.uniform(-80, 80), rng.uniform(0, 300))
                 for _ in range(rng.randrange(0, 3))]
        tail = rng.choice([None, (rng.uniform(0, 300), rng.uniform(0, 600))])
        collect = (rows, start, rng.uniform(0, 5), later, tail)
        c_cost = (kernels.DeployStopCost(*deploy[:2], *c_models, *deploy[2:]),
                  kernels.CollectStopCost(rows, *c_models, *collect[1:]))
        py_cost = (deploy_stop_cost(*deploy[:2], *py_models, *deploy[2:]),
                   collect_stop_cost(rows, *py_models, *collect[1:]))
        for _ in range(20):
            x, y = cx + rng.uniform(-25, 25), cy + rng.uniform(-25, 25)
            for ours, ref in zip(c_cost, py_cost, strict=True):
                got = ours(x, y)
                assert got == ref(x, y)
                seen["inf" if got == math.inf else "finite"] += 1
    assert min(seen.values()) > 500, seen
    with pytest.raises(TypeError):  # only the compiled time model
        kernels.DeployStopCost(*deploy[:2], *py_models, *deploy[2:])


@native
def test_quick_placement_kernels_match_python() -> None:
    """The collection's quick placement: candidates scored from a previous stop (hops of no length
    included), then the one the carrier leaves soonest from, with and without the rovers' ready
    time counted, ties to the first."""
    from planners.collect.path import quickest, score_candidates
    from planners.core.timing import _python_leg, _python_stepper

    assert kernels is not None
    rng = random.Random(19)
    seen = {"capped": 0, "ready": 0, "tie": 0}
    for _ in range(500):
        v, a, w = rng.uniform(2, 20), rng.choice([None, rng.uniform(0.5, 5)]), rng.choice([None, 1.0])
        step, py_step = kernels.Stepper(v, a, w), _python_stepper(v, a, w)
        ra = rng.choice([None, 2.0])
        leg, py_leg = kernels.Leg(5.0, ra, 1.0), _python_leg(5.0, ra, 1.0)
        prev = (rng.uniform(-50, 50), rng.uniform(-50, 50))
        cands = [(rng.uniform(-50, 50), rng.uniform(-50, 50)) for _ in range(rng.randrange(1, 4))]
        if rng.random() < 0.3:
            cands.append(prev)
            cands.append(cands[0])  # a tie
        nxt = rng.choice([None, (rng.uniform(-50, 50), rng.uniform(-50, 50))])
        heading = rng.uniform(-4, 4)
        scored = kernels.score_candidates(step, cands, prev, heading, nxt)
        assert scored == score_candidates(py_step, cands, prev, heading, nxt)
        rows = [(rng.uniform(-50, 50), rng.uniform(-50, 50), rng.uniform(0, 100)) for _ in range(5)]
        t, load = rng.uniform(0, 100), rng.uniform(0, 5)
        for cap in (0.0, math.inf, t + rng.uniform(0, 20)):
            got = kernels.quickest(scored, t, cap, leg, rows, load)
            ref = quickest(scored, t, cap, py_leg, rows, load)
            assert got == ref and got[0] is ref[0]
            seen["capped" if cap == 0.0 else "ready"] += 1
        seen["tie"] += len(cands) > len(set(cands))
    assert min(seen.values()) > 50, seen
    with pytest.raises(ValueError):
        kernels.quickest((), 0.0, 0.0, leg, [], 0.0)


@native
def test_route_times_kernels_match_python() -> None:
    """Eq. 5.2's departures and suffix times of random routes, short (plain Python) and long
    (numpy), with rovers that hold the carrier up and rovers that are ready before it comes; the
    deployment's arrivals, finishes and their running maxima likewise."""
    from planners.collect.path import route_times
    from planners.deploy.path import deploy_times

    assert kernels is not None
    rng = random.Random(23)
    for _ in range(400):
        n = rng.choice([1, 2, 5, 23, 24, 60, 300])
        hop = [rng.choice([0.0, rng.uniform(0, 30)]) for _ in range(n)]
        ready = [rng.uniform(0, 40 * n) * rng.choice([0.0, 1.0]) for _ in range(n)]
        load = rng.choice([0.0, rng.uniform(0, 5)])
        assert kernels.route_times(hop, ready, load) == route_times(hop, ready, load)
        fly = [rng.uniform(0, 20) for _ in range(n)]
        assert kernels.deploy_times(hop, fly, load) == deploy_times(hop, fly, load)
    assert kernels.deploy_times([], [], 1.0) == deploy_times([], [], 1.0)
    with pytest.raises(ValueError):
        kernels.route_times([], [], 1.0)


_PLANS = """
import json, random, sys
sys.path.insert(0, {root!r})
from bench.scaling import random_deploy
from bench.scaling_collect import random_problem
from planners import COLLECT_PLANNERS, DEPLOY_PLANNERS
from planners.core.native import kernels
out = {{"native": kernels is not None, "plans": []}}
for n, seed in ((7, 1), (40, 2), (120, 3)):
    rng = random.Random(seed)
    for plan in (DEPLOY_PLANNERS["lee"](random_deploy(rng, n, 200.0, rng.uniform(5.0, 20.0))),
                 COLLECT_PLANNERS["lee"](random_problem(n, seed, 200.0, ranges=(5.0, 20.0)))):
        out["plans"].append([plan.makespan, [list(s.position) for s in plan.stops]])
print(json.dumps(out))
"""


def _plans(pure: bool) -> dict:
    env = {**os.environ, "FLEETCTL_PURE_PYTHON": "1" if pure else "0"}
    got = subprocess.run([sys.executable, "-c", _PLANS.format(root=str(ROOT))], env=env, check=True,
                         capture_output=True, text=True, timeout=300)
    return json.loads(got.stdout)


@native
@pytest.mark.slow
def test_plans_are_the_same_floats_with_and_without_the_kernels() -> None:
    compiled, python = _plans(pure=False), _plans(pure=True)
    assert compiled["native"] and not python["native"]
    assert compiled["plans"] == python["plans"]
