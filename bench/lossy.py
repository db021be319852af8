"""Planned vs flown makespan through a lossy link: ``missions/recon.yaml`` deployed and collected
(and a 3D paper scenario) on the simulated fleet with every packet dropped at ``rate`` both ways
(the ``packet_loss`` fault) at 0, 20, 30 and 40 %, at ``--speedup`` (default 10). Flown makespan is
in simulated seconds; "x plan" is flown / planned.

    python bench/lossy.py [--speedup 10] [--rates 0,0.2,0.3,0.4] [--jobs 2] [--seeds 1]

Prints a markdown table.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import sys
import tempfile
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

import yaml  # noqa: E402
from flight import _fly_job  # noqa: E402

SCENARIOS = [(ROOT / "missions" / "recon.yaml", "deploy"), (ROOT / "missions" / "recon.yaml", "collect"),
             (ROOT / "missions" / "paper" / "deploy_6tasks_3d_d15.yaml", "deploy")]


def _lossy_copy(src: Path, rate: float, seed: int, tmp: Path) -> Path:
    d = yaml.safe_load(src.read_text())
    sim = dict(d.get("sim") or {})
    faults = [f for f in sim.get("faults") or [] if f.get("kind") != "packet_loss"]
    if rate > 0:
        faults.append({"kind": "packet_loss", "rate": rate})
    sim["faults"] = faults
    d["sim"] = sim
    d.setdefault("planner", {})["seed"] = seed
    out = tmp / f"{src.stem}-loss{int(rate * 100)}-s{seed}.yaml"
    out.write_text(yaml.safe_dump(d, sort_keys=False))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--speedup", type=float, default=10.0)
    ap.add_argument("--rates", default="0,0.2,0.3,0.4")
    ap.add_argument("--seeds", type=int, default=1)
    ap.add_argument("--jobs", type=int, default=2)
    args = ap.parse_args(argv)
    rates = [float(r) for r in args.rates.split(",")]
    with tempfile.TemporaryDirectory() as tmp:
        jobs = [(str(_lossy_copy(src, rate, seed, Path(tmp))), kind, args.speedup, tmp, rate)
                for src, kind in SCENARIOS for rate in rates for seed in range(1, args.seeds + 1)]
        with mp.get_context("spawn").Pool(args.jobs) as pool:
            rows: list[dict[str, Any]] = pool.map(_fly_job, [j[:4] for j in jobs])
    print("| mission | kind | loss % | speedup | planned s | flown s | x plan | result |")
    print("|---|---|---:|---:|---:|---:|---:|---|")
    worst = 0.0
    for (_src, kind, speedup, _tmp, rate), r in zip(jobs, rows, strict=True):
        ratio = r["flown"] / r["planned"] if r.get("flown") and r.get("planned") else None
        if ratio is not None and rate > 0:
            worst = max(worst, ratio)
        name = r["mission"].split("-loss")[0]
        print(f"| {name} | {kind} | {rate * 100:.0f} | {speedup:g} | {r['planned'] or 0:.1f} | "
              f"{r['flown'] or 0:.1f} | {'-' if ratio is None else f'{ratio:.2f}'} | {r['result']}"
              + (f" ({r['error']})" if r.get("error") else "") + " |")
    print(f"\nworst flown / planned with a lossy link: {worst:.2f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
