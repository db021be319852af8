"""Where the quick plan's CPU time goes, phase by phase, and what each phase gains (the speed
targets: deploy 100 tasks ≤ 10 ms, 1000 ≤ 100 ms; collect 100 rovers ≤ 20 ms, 1000 ≤ 150 ms).

On the instances of bench/scaling.py (deployment) and bench/scaling_collect.py (collection, ranges
5–20 m), ``lee_clusters`` / ``lee_route`` report each phase through their ``trace``
(``planners.core.trace``); the CPU time between two reports is the phase's. Per phase: the median
CPU ms over the seeds, the mean makespan gain in per cent of the dissertation's route (Algorithms
4.1–4.2 / 5.1–5.2: the first phase), and the phase's cost per per cent gained. ``route build`` is
the CPU time of timing one whole route of the final plan from scratch (``PathBuilder.route``), the
unit every search move is paid in. A phase that runs in several rounds is summed.

Run: ``python bench/phases.py [--seeds 5] [--sizes 100,1000]`` (prints markdown).
"""

from __future__ import annotations

import argparse
import random
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.scaling import random_deploy  # noqa: E402
from bench.scaling_collect import random_problem  # noqa: E402
from planners.collect import lee as collection  # noqa: E402
from planners.collect.instance import CollectInstance  # noqa: E402
from planners.collect.path import PathBuilder as CollectBuilder  # noqa: E402
from planners.deploy import lee as deploy  # noqa: E402
from planners.deploy.cluster import DeployInstance  # noqa: E402
from planners.deploy.path import PathBuilder as DeployBuilder  # noqa: E402

TARGET_MS = {("deploy", 100): 10.0, ("deploy", 1000): 100.0, ("collect", 100): 20.0, ("collect", 1000): 150.0}


class PhaseClock:
    """A ``Trace`` that books the CPU time and the makespan gained since the last report to the
    reported phase (the first report's makespan is the reference, ``start``)."""

    def __init__(self) -> None:
        self.ms: dict[str, float] = {}
        self.gain: dict[str, float] = {}
        self.start = self._was = float("nan")
        self._last = time.process_time()

    def __call__(self, phase: str, makespan: float) -> None:
        now = time.process_time()
        self.ms[phase] = self.ms.get(phase, 0.0) + (now - self._last) * 1e3
        if not self.ms.keys() - {phase}:  # the first phase
            self.start = self._was = makespan
        self.gain[phase] = self.gain.get(phase, 0.0) + self._was - makespan
        self._was, self._last = makespan, now


def _min_ms(f: Callable[[], object], reps: int = 3) -> float:
    best = float("inf")
    for _ in range(reps):
        t0 = time.process_time()
        f()
        best = min(best, (time.process_time() - t0) * 1e3)
    return best


def deploy_run(n: int, seed: int) -> tuple[PhaseClock, float]:
    rng = random.Random(1000 * n + seed)
    problem = random_deploy(rng, n, 200.0, rng.uniform(5.0, 20.0))
    deploy.lee_clusters(problem)  # warm (first calls pay for imports and caches)
    clock = PhaseClock()
    clusters, _, _ = deploy.lee_clusters(problem, trace=clock)
    builder = DeployBuilder(DeployInstance(problem))
    return clock, _min_ms(lambda: builder.route(clusters))


def collect_run(n: int, seed: int) -> tuple[PhaseClock, float]:
    problem = random_problem(n, 1000 * n + seed, 200.0, ranges=(5.0, 20.0))
    collection.lee_route(problem)
    clock = PhaseClock()
    _, route = collection.lee_route(problem, trace=clock)
    builder = CollectBuilder(CollectInstance(problem))
    return clock, _min_ms(lambda: builder.route(route.clusters))


def table(kind: str, n: int, seeds: int) -> str:
    run = deploy_run if kind == "deploy" else collect_run
    clocks, builds = zip(*(run(n, s) for s in range(seeds)), strict=True)
    phases = list(clocks[0].ms)
    lines = [f"**{kind} {n}** ({seeds} instances; target {TARGET_MS.get((kind, n), float('nan')):g} ms; "
             f"one route build {statistics.median(builds):.2f} ms)", "",
             "| phase | median CPU ms | mean gain % | ms per % gained |", "|---|---|---|---|"]
    total = [sum(c.ms.values()) for c in clocks]
    for k, phase in enumerate(phases):
        ms = statistics.median(c.ms.get(phase, 0.0) for c in clocks)
        if k == 0:
            lines.append(f"| {phase} | {ms:.1f} | — | — |")
            continue
        gain = statistics.mean(c.gain.get(phase, 0.0) / c.start * 100 for c in clocks)
        per = f"{ms / gain:.1f}" if gain > 1e-6 else "—"
        lines.append(f"| {phase} | {ms:.1f} | {gain:.3f} | {per} |")
    lines.append(f"| **total** | **{statistics.median(total):.1f}** | | |")
    first = statistics.median(c.ms[phases[0]] for c in clocks)
    after = statistics.mean(sum(c.gain.values()) / c.start * 100 for c in clocks)
    target = TARGET_MS.get((kind, n))
    share = f" = {first / target * 100:.0f} % of the target" if target else ""
    lines += ["", f"The dissertation's algorithm alone: {first:.1f} ms{share}; the phases after it take "
              f"{after:.2f} % off its makespan."]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> str:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--sizes", default="100,1000")
    args = ap.parse_args(argv)
    out = [table(kind, int(n), args.seeds) for kind in ("deploy", "collect") for n in args.sizes.split(",")]
    text = "\n\n".join(out)
    print(text)
    return text


if __name__ == "__main__":
    main()
