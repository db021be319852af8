"""Headroom of the quick plan against a joint re-optimisation of every stop (the target: ≤ 0.5 %).

For n = 20, 50, 100 tasks (rovers) on the instances of bench/scaling.py (deployment, 200 m square)
and bench/scaling_collect.py (collection, 200 m square, ranges 5–20 m), ``lee``'s quick plan keeps
its groups and order while every stop is re-placed jointly: block coordinate descent (each stop by
a compass search with all others fixed, sweeps until no stop moves, steps down to 0.1 mm; for
collection the chapter's fine candidate placement first). Headroom = (T_quick − T_joint) / T_quick.

Run: ``python bench/headroom.py [--seeds 5] [--sizes 20,50,100]`` (prints markdown).
"""

from __future__ import annotations

import argparse
import importlib.util
import random
import statistics
import sys
from pathlib import Path
from types import ModuleType

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from planners.collect import lee as collection  # noqa: E402
from planners.collect.polish import polish  # noqa: E402
from planners.deploy import lee as deploy  # noqa: E402
from planners.deploy.cluster import DeployInstance  # noqa: E402
from planners.deploy.path import PathBuilder, Route  # noqa: E402


def _bench(name: str) -> ModuleType:
    spec = importlib.util.spec_from_file_location(name, ROOT / "bench" / f"{name}.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def deploy_headroom(n: int, seed: int) -> float:
    rng = random.Random(1000 * n + seed)
    problem = _bench("scaling").random_deploy(rng, n, 200.0, rng.uniform(5.0, 20.0))
    clusters, positions, quick = deploy.lee_clusters(problem)
    inst = DeployInstance(problem)
    builder = PathBuilder(inst)
    route = Route(builder, clusters, [inst.geometry(c) for c in clusters], list(positions))
    joint = deploy._polish(builder, route, sweeps=200, tol=1e-4)
    return max(route.makespan - joint.makespan, 0.0) / route.makespan * 100


def collect_headroom(n: int, seed: int) -> float:
    problem = _bench("scaling_collect").random_problem(n, 1000 * n + seed, 200.0, ranges=(5.0, 20.0))
    builder, route = collection.lee_route(problem)
    joint = polish(builder, route, sweeps=20, level=2)
    joint = collection.compass(builder, joint, sweeps=200, tol=1e-4)
    return max(route.makespan - joint.makespan, 0.0) / route.makespan * 100


def main(argv: list[str] | None = None) -> str:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--sizes", default="20,50,100")
    args = ap.parse_args(argv)
    lines = ["| kind | n | instances | mean headroom % | max headroom % |", "|---|---|---|---|---|"]
    for kind, f in (("deploy", deploy_headroom), ("collect", collect_headroom)):
        for n in (int(s) for s in args.sizes.split(",")):
            h = [f(n, s) for s in range(args.seeds)]
            lines.append(f"| {kind} | {n} | {len(h)} | {statistics.mean(h):.3f} | {max(h):.3f} |")
    text = "\n".join(lines)
    print(text)
    return text


if __name__ == "__main__":
    main()
