"""Fuzz ``fleetctl plan --json`` with mutated mission files (tests/fuzz/mutate.py).

Each case runs in a forked worker process (the parent has imported everything once) with a
per-case wall timeout (``--timeout``, 5 s) and an address-space cap (``--memory-mb``, RLIMIT_AS
500 MB); ``--jobs`` workers run at once. Prints a markdown table by mutation kind: cases, exit 0
with valid finite JSON, exit 2 with a message, traceback (or any other bad exit / bad JSON), hang
(over the timeout), over memory. ``--save DIR`` writes every failing case there.

    python bench/fuzz_missions.py --cases 10000 --jobs 2 --seed 1
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from collections import Counter, defaultdict
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy: keeps each worker's address space small
os.environ.setdefault("OMP_NUM_THREADS", "1")
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import multiprocessing as mp  # noqa: E402
import resource  # noqa: E402

import fleetctl.cli  # noqa: E402, F401 - imported once in the parent, inherited by every fork
import planners  # noqa: E402, F401
from tests.fuzz.mutate import KINDS, Case, mutations, run_case  # noqa: E402

COLUMNS = ("cases", "exit 0 valid JSON", "exit 2 message", "traceback", "hang", "over memory")


def _worker(case: Case, workdir: str, memory_mb: int, conn: mp.connection.Connection) -> None:
    limit = memory_mb * 1024 * 1024
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    try:
        res = run_case(case.text, Path(workdir) / f"case{case.index}.yaml", case.collect)
        outcome = res.outcome
        if outcome == "traceback" and "MemoryError" in res.detail:
            outcome = "memory"
        conn.send((outcome, res.detail[-2000:]))
    except MemoryError:
        conn.send(("memory", "MemoryError"))
    finally:
        conn.close()
    os._exit(0)  # no atexit handlers / flushing of inherited state


def run(cases: int, seed: int, jobs: int, timeout: float, memory_mb: int,
        save: Path | None) -> dict[str, Counter[str]]:
    ctx = mp.get_context("fork")
    table: dict[str, Counter[str]] = defaultdict(Counter)
    todo = iter(mutations(seed, cases))
    running: list[tuple[Case, mp.process.BaseProcess, mp.connection.Connection, float]] = []
    failures: list[tuple[Case, str, str]] = []
    with tempfile.TemporaryDirectory(prefix="fuzz-missions-") as workdir:
        exhausted = False
        while running or not exhausted:
            while not exhausted and len(running) < jobs:
                case = next(todo, None)
                if case is None:
                    exhausted = True
                    break
                recv, send = ctx.Pipe(duplex=False)
                p = ctx.Process(target=_worker, args=(case, workdir, memory_mb, send), daemon=True)
                p.start()
                send.close()
                running.append((case, p, recv, time.monotonic()))
            time.sleep(0.002)
            still = []
            for case, p, recv, t0 in running:
                outcome = None
                detail = ""
                if recv.poll():
                    try:
                        outcome, detail = recv.recv()
                    except EOFError:
                        outcome, detail = "crash", f"worker died (exit {p.exitcode})"
                elif not p.is_alive():
                    outcome, detail = ("memory" if p.exitcode and p.exitcode < 0 else "crash",
                                       f"worker died (exit {p.exitcode})")
                elif time.monotonic() - t0 > timeout:
                    p.kill()
                    outcome, detail = "hang", f"still running after {timeout:g} s"
                if outcome is None:
                    still.append((case, p, recv, t0))
                    continue
                p.join(5)
                recv.close()
                table[case.kind][outcome] += 1
                if outcome not in ("ok", "error"):
                    failures.append((case, outcome, detail))
            running = still
    if save is not None:
        save.mkdir(parents=True, exist_ok=True)
        for case, outcome, detail in failures:
            stem = f"{case.kind}-{case.index}-{outcome}"
            (save / f"{stem}.yaml").write_bytes(case.text.encode("utf-8", "surrogateescape")[:200_000])
            (save / f"{stem}.txt").write_text(f"base {case.base}\n{detail}\n", encoding="utf-8")
    for case, outcome, detail in failures[:20]:
        last = detail.strip().splitlines()[-1:]
        print(f"<!-- {case.kind} #{case.index} ({case.base}): {outcome}: {last} -->",
              file=sys.stderr)
    return table


def markdown(table: dict[str, Counter[str]]) -> str:
    rows = ["| kind | " + " | ".join(COLUMNS) + " |", "|---" * (len(COLUMNS) + 1) + "|"]
    total: Counter[str] = Counter()
    for kind in [k for k in KINDS if k in table]:
        c = table[kind]
        total.update(c)
        rows.append(_row(kind, c))
    rows.append(_row("**all**", total))
    return "\n".join(rows)


def _row(name: str, c: Counter[str]) -> str:
    bad = c["traceback"] + c["bad_json"] + c["bad_exit"] + c["crash"]
    cells = [sum(c.values()), c["ok"], c["error"], bad, c["hang"], c["memory"]]
    return f"| {name} | " + " | ".join(str(x) for x in cells) + " |"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--timeout", type=float, default=5.0, help="wall seconds per case")
    ap.add_argument("--memory-mb", type=int, default=500, help="RLIMIT_AS of a worker")
    ap.add_argument("--save", type=Path, help="write failing cases here")
    args = ap.parse_args()
    t0 = time.monotonic()
    table = run(args.cases, args.seed, args.jobs, args.timeout, args.memory_mb, args.save)
    print(markdown(table))
    print(f"\n{args.cases} cases, seed {args.seed}, {args.jobs} jobs, timeout {args.timeout:g} s, "
          f"RLIMIT_AS {args.memory_mb} MB: {time.monotonic() - t0:.0f} s")
    bad = sum(c[k] for c in table.values() for k in ("traceback", "bad_json", "bad_exit", "crash", "hang",
                                                      "memory"))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
