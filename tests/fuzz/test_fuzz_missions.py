"""Mutated mission files never crash, hang or print non-finite JSON.

``test_fuzz_in_process`` runs a few hundred seeded mutations (tests/fuzz/mutate.py) through
``fleetctl plan --json`` in this process; ``test_reproducers`` runs every file of
``tests/fuzz/cases/`` (each one crashed, hung or printed Infinity before the loader limits) and
checks the message. ``bench/fuzz_missions.py`` runs thousands with a timeout and a memory cap.
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from tests.fuzz.mutate import KINDS, check_output, mutations, run_case

CASES = Path(__file__).resolve().parent / "cases"
CASE_TIMEOUT = 20.0  # s of one case here (CPU shared: generous; the bench uses 5 s per case)

EXPECTED = {
    "alias_bomb_8x8.yaml": ":35: alias *a4",
    "alias_recursive.yaml": ":30: alias *r refers to the node it is inside",
    "bool_maybe_tag.yaml": ":11: cannot read the value",
    "deploy_range_1e6_complete_roadmap.yaml": "planner.roadmap: the roadmap would have about",
    "int_400_digits.yaml": ":12: a number written with 400 characters",
    "max_speed_1.79e+308.yaml": ":12: carrier.max_speed: 1.79e+308 is out of range",
    "nesting_20000.yaml": ":30: lists/mappings nested more than 32 levels",
    "nesting_600.yaml": ":30: lists/mappings nested more than 32 levels",
    "obstacles_600.yaml": "obstacles: 600 entries are too many; give at most 500",
    "obstacles_480_small.yaml": None,  # within the limits: plans
    "roadmap_xi1_1e+308.yaml": "planner.roadmap.xi1: 1e+308 is out of range",
    "roadmap_xi1_256.yaml": "planner.roadmap: the global roadmap would have 25750 nodes",
    "timestamp_bad.yaml": ":11: cannot read the value (month must be in 1..12)",
    "unload_time_1e+308.yaml": ":15: carrier.unload_time: 1e+308 is out of range",
    # found by `bench/fuzz_missions.py --cases 10000` (hang, over 500 MB, segfault under RLIMIT_AS):
    # local PRMs (xi3/xi4) or phi on top of a long edge radius made the roadmap a dense graph
    "fuzz10k_roadmap_1439-hang.yaml": "roadmap would have about",
    "fuzz10k_roadmap_2603-memory.yaml": "roadmap would have about",
    "fuzz10k_roadmap_4571-crash.yaml": "roadmap would have about",
    "fuzz10k_roadmap_7643-hang.yaml": "roadmap would have about",
}


def test_every_reproducer_has_an_expectation() -> None:
    assert sorted(p.name for p in CASES.glob("*.yaml")) == sorted(EXPECTED)


@pytest.mark.parametrize("name", sorted(EXPECTED))
@pytest.mark.parametrize("collect", [False, True])
def test_reproducers(tmp_path: Path, name: str, collect: bool) -> None:
    t0 = time.monotonic()
    res = run_case((CASES / name).read_text(encoding="utf-8"), tmp_path / name, collect)
    assert time.monotonic() - t0 < CASE_TIMEOUT
    want = EXPECTED[name]
    if want is None:
        assert res.outcome == "ok", res.detail
    else:
        assert res.outcome == "error", res.detail
        assert res.detail.startswith(f"fleetctl: error: {tmp_path / name}")
        if collect and "has no 'collection' section" in res.detail:
            return  # a deployment-only mission: --collect is refused first
        assert want in res.detail


def test_check_output_refuses_non_finite_json() -> None:
    assert check_output(0, '{"arrive": Infinity}', "").outcome == "bad_json"
    assert check_output(0, '{"arrive": NaN}', "").outcome == "bad_json"
    assert check_output(0, '{"arrive": 1.5}', "").outcome == "ok"
    assert check_output(2, "", "fleetctl: error: f: x: bad").outcome == "error"
    assert check_output(1, "", "Traceback ...").outcome == "bad_exit"


@pytest.mark.slow
def test_mutations_are_seeded() -> None:
    a = [(c.kind, c.text) for c in mutations(5, 24)]
    assert a == [(c.kind, c.text) for c in mutations(5, 24)]
    assert {k for k, _ in a} == set(KINDS)


@pytest.mark.slow
def test_fuzz_in_process(tmp_path: Path) -> None:
    """240 mutated files (20 of each kind): exit 0 with finite JSON or exit 2 with a message."""
    bad = []
    slow = []
    for case in mutations(seed=13, n=20 * len(KINDS)):
        t0 = time.monotonic()
        res = run_case(case.text, tmp_path / "m.yaml", case.collect)
        took = time.monotonic() - t0
        if res.outcome not in ("ok", "error"):
            bad.append((case.kind, case.index, case.base, res.outcome, res.detail[-600:]))
        if took > CASE_TIMEOUT:
            slow.append((case.kind, case.index, round(took, 1)))
    assert not bad, bad
    assert not slow, slow


def test_forced_roadmap_planner_on_a_huge_open_mission_is_a_message(tmp_path: Path) -> None:
    """The loader checks the roadmap only when the mission uses it; ``--planner lee-graph`` on a
    wide open-space mission is refused by the planner's own node cap (planners.roadmap.graph.MAX_NODES)."""
    import contextlib
    import io

    import yaml

    from fleetctl.cli import main

    d = {"name": "wide", "carrier": {"position": [0, 0], "max_speed": 15.0},
         "rovers": {"max_speed": 5.0, "deploy_range": 50.0},
         "tasks": [{"id": "a", "position": [90_000, 0, 2]}, {"id": "b", "position": [0, 90_000, 2]}]}
    f = tmp_path / "wide.yaml"
    f.write_text(yaml.safe_dump(d), encoding="utf-8")
    out, err = io.StringIO(), io.StringIO()
    t0 = time.monotonic()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(["plan", "--json", "-m", str(f), "--planner", "lee-graph"])
    assert rc == 2 and "roadmap would have" in err.getvalue() and time.monotonic() - t0 < CASE_TIMEOUT


def test_ten_thousand_small_obstacles(tmp_path: Path) -> None:
    """The finding: 10,000 small obstacles ran for more than 45 s (generated: too big to store)."""
    import random

    text = (CASES / "obstacles_600.yaml").read_text(encoding="utf-8")
    rng = random.Random(3)
    obs = ",".join(f"[[{x:.2f},{y:.2f}],[{x + 0.05:.2f},{y:.2f}],[{x + 0.05:.2f},{y + 0.05:.2f}]]"
                   for x, y in ((rng.uniform(0, 100), rng.uniform(95, 100)) for _ in range(10_000)))
    start, end = text.index("obstacles:"), text.index("bounds:")
    t0 = time.monotonic()
    res = run_case(text[:start] + f"obstacles: [{obs}]\n" + text[end:], tmp_path / "m.yaml")
    assert res.outcome == "error" and time.monotonic() - t0 < CASE_TIMEOUT
    assert "larger than 100000 values" in res.detail or "entries are too many" in res.detail
